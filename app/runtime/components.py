"""The runtime's exchangeable parts, typed: a `WorldMap` (object, voxel or ground truth) and the HTMPC."""

from __future__ import annotations

from typing import TYPE_CHECKING

from app.map_kind import MapKind
from core.mapping.world_map import WorldMap
from core.params import HTMPCParams, MappingParams
from core.robot.model import RobotModel
from core.sim.world import SimWorld

if TYPE_CHECKING:
    from core.htmpc import HTMPC


def make_map(kind: MapKind, robot: RobotModel, world: SimWorld | None, params: MappingParams) -> WorldMap:
    """A map of `kind`: 'object' (POCD), 'voxel' (static-world baseline) or 'ground_truth' (simulation only)."""
    if kind == "ground_truth":
        if world is None:
            raise ValueError("the ground-truth map needs the embedded simulation")
        from app.runtime.ground_truth_map import GroundTruthMap

        return GroundTruthMap(world, params)
    if kind == "object":
        from core.mapping import ObjectMapper

        return _with_unknown_space(ObjectMapper(robot, params), robot, params)
    if kind == "voxel":
        from core.mapping import VoxelMap

        return _with_unknown_space(VoxelMap(robot, params), robot, params)
    raise ValueError(f"unknown map kind {kind!r}: object, voxel or ground_truth")  # pyright: ignore[reportUnreachable]  (untyped callers)


def _with_unknown_space(world_map: WorldMap, robot: RobotModel, params: MappingParams) -> WorldMap:
    """A perceived map with unknown space as an obstacle when `params.unknown_space` says so (the ground truth
    needs none: it knows every box, dark ones too)."""
    if params.unknown_space != "obstacle":
        return world_map
    from core.mapping.unknown_space_map import UnknownSpaceMap

    return UnknownSpaceMap(world_map, robot, params)


def make_controller(robot: RobotModel, params: HTMPCParams) -> HTMPC:
    """The lexicographic HTMPC with `solve(state, refs, edf) -> Plan` and `reset()`."""
    from core.htmpc import HTMPC

    return HTMPC(robot, params)
