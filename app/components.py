"""Build the runtime's exchangeable parts: the map (object, voxel or ground truth) and the controller."""

from __future__ import annotations

from core.params import HTMPCParams, MappingParams
from core.robot.model import RobotModel
from core.sim.world import SimWorld


def make_map(kind: str, robot: RobotModel, world: SimWorld | None, params: MappingParams):
    """A map with `integrate`, `snapshot`, `local_edf`, `occupied_points` and `timings_ms`."""
    if kind == "ground_truth":
        if world is None:
            raise ValueError("the ground-truth map needs the embedded simulation")
        from app.ground_truth_map import GroundTruthMap

        return GroundTruthMap(world, params)
    if kind == "object":
        from core.mapping import ObjectMapper

        return ObjectMapper(robot, params)
    if kind == "voxel":
        from core.mapping import VoxelMap

        return VoxelMap(robot, params)
    raise ValueError(f"unknown map kind {kind!r}: object, voxel or ground_truth")


def make_controller(robot: RobotModel, params: HTMPCParams):
    """The lexicographic HTMPC with `solve(state, refs, edf) -> Plan` and `reset()`."""
    from core.htmpc import HTMPC

    return HTMPC(robot, params)
