"""`UnknownSpaceMap`: any `WorldMap` with unknown space as an obstacle (docs/method.md, "Unknown space is not
free"; `MappingParams.unknown_space`).

It feeds every depth frame to the map it wraps and to an `UnknownFloor`, and answers `local_edf` with the
wrapped map's field joined with the unknown columns (`unknown_floor.unknown_columns`), the `UnknownSpace`
attached for the planner and the operator. `snapshot` and `occupied_points` are the wrapped map's own: what
the map holds, not what it could not see (the experiments count phantoms on them).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from core.mapping.self_filter import SelfFilter
from core.mapping.unknown_floor import UnknownFloor, unknown_columns
from core.mapping.world_map import WorldMap
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import LocalEDF, ObjectMapSnapshot, Observation


class UnknownSpaceMap:
    """`inner` behind the `WorldMap` interface, plus the unknown floor; other attributes are the inner map's."""

    def __init__(self, inner: WorldMap, robot: RobotModel, params: MappingParams) -> None:
        self.inner = inner
        self.unknown = UnknownFloor(params)
        self.self_filter = SelfFilter(robot, params.self_filter_margin_m)
        self._unknown_ms = 0.0

    @property
    def timings_ms(self) -> dict[str, float]:
        return {**self.inner.timings_ms, "unknown": self._unknown_ms}

    def integrate(self, obs: Observation) -> None:
        self.inner.integrate(obs)
        t0 = time.perf_counter()
        for frame in obs.frames:
            if frame.camera in self.unknown.params.unknown_cameras:  # the body's kinematics only where it is used
                self.unknown.integrate(frame, self.self_filter.body(obs.q_at(frame.t)))
        self._unknown_ms = (time.perf_counter() - t0) * 1e3

    def snapshot(self) -> ObjectMapSnapshot:
        return self.inner.snapshot()

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        """The wrapped map's signed EDF with the unknown columns as obstacles."""
        return unknown_columns(self.inner.local_edf(centre_xy), self.unknown.space())

    def occupied_points(self) -> np.ndarray:
        return self.inner.occupied_points()

    def __getattr__(self, name: str) -> Any:
        """The wrapped map's own attributes (its objects, counters) read through (never dunders: pickling)."""
        if name.startswith("__") or name in ("inner", "unknown", "self_filter", "_unknown_ms"):
            raise AttributeError(name)
        return getattr(self.inner, name)
