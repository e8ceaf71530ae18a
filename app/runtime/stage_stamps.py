"""`StageStamps`: wall-clock stamps of the live loops' stages, for measuring how long a change in the world takes
to reach the robot's commands (`bench/reaction.py`).

A `ClosedLoop` whose `stamps` is set appends one small record per physics step, integration, control step and
command to bounded deques (O(1), no locks: `deque.append` is atomic under the GIL; a reader copies with
`list()`); with `stamps` None (the default) nothing is recorded. Nothing here computes anything while the loops
run: the reader analyses the records afterwards.

Wall time is `time.perf_counter()` (s); robot time is the loop's (simulated in simulation). The physics records
pair the two, so a moment of simulated time (a frame's exposure, its stamp) can be placed on the wall clock: the
physics step that reached it.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from core.types import DepthFrame, LocalEDF, Plan

KEEP_S = 30.0
"""How much recent history each deque holds (s of wall time at the default rates)."""


@dataclass(frozen=True)
class FrameStamp:
    """A frame as integrated: its camera, exposure and stamp (robot s), and where it looked from."""

    camera: str
    exposure_t: float
    stamp_t: float
    K: np.ndarray
    T_world_camera: np.ndarray
    shape: tuple[int, int]

    @staticmethod
    def of(frame: DepthFrame, latency_s: float) -> FrameStamp:
        """`frame` placed at its exposure (`frame.t`), stamped `latency_s` later."""
        return FrameStamp(frame.camera, frame.t, frame.t + latency_s, frame.K, frame.T_world_camera,
                          (int(frame.depth.shape[0]), int(frame.depth.shape[1])))

    def sees(self, points: np.ndarray, range_m: float) -> bool:
        """Whether any of `points` (world, P×3) lies in this camera's view, in front of it and within `range_m`
        (occlusion aside)."""
        T = self.T_world_camera
        p = (np.atleast_2d(np.asarray(points, float)) - T[:3, 3]) @ T[:3, :3]
        p = p[(p[:, 2] > 0.0) & (p[:, 2] <= range_m)]
        uvw = p @ self.K.T
        u, v = uvw[:, 0] / uvw[:, 2], uvw[:, 1] / uvw[:, 2]
        return bool(np.any((u >= 0.0) & (u < self.shape[1]) & (v >= 0.0) & (v < self.shape[0])))


@dataclass(frozen=True)
class IntegrationStamp:
    """One map integration: its frames, wall start and end (an isolated map: when its result, with the EDF, was
    handed back), the EDF it produced (an isolated map builds one around the robot after each integration; None
    otherwise) and how long building that EDF took, just before the end (ms)."""

    frames: tuple[FrameStamp, ...]
    wall_start: float
    wall_end: float
    edf: LocalEDF | None
    edf_ms: float


@dataclass(frozen=True)
class ControlStamp:
    """One control step: its robot time, wall at wake, once its EDF was in hand, at solve start and end, and
    the EDF and plan (None: no plan)."""

    t: float
    wall_wake: float
    wall_edf: float
    wall_solve_start: float
    wall_solve_end: float
    edf: LocalEDF | None
    plan: Plan | None


@dataclass(frozen=True)
class CommandStamp:
    """One velocity command: wall and robot time, the base's commanded planar velocity (world), its plan, and the
    thread that sent it (`io` every command period; `control` for a new plan's first command)."""

    wall: float
    t: float
    base_v: tuple[float, float]
    plan: Plan | None
    thread: str = ""


class StageStamps:
    """Bounded recent history of the live loops' stages (see the module docstring)."""

    def __init__(self, keep_s: float = KEEP_S, physics_hz: float = 100.0, command_hz: float = 100.0) -> None:
        self.physics: deque[tuple[float, float]] = deque(maxlen=int(keep_s * physics_hz))
        """(robot time after the step, wall time after the step)."""
        self.integrations: deque[IntegrationStamp] = deque(maxlen=int(keep_s * 40))
        self.controls: deque[ControlStamp] = deque(maxlen=int(keep_s * 40))
        self.commands: deque[CommandStamp] = deque(maxlen=int(keep_s * command_hz))
        self.frames_integrated: dict[str, int] = {}
        """Frames the map integrated since the stamps were set, per camera (the whole run, not only `keep_s`)."""

    @staticmethod
    def now() -> float:
        return time.perf_counter()

    def physics_step(self, t: float) -> None:
        self.physics.append((t, time.perf_counter()))

    def integration(self, stamp: IntegrationStamp) -> None:
        self.integrations.append(stamp)
        for frame in stamp.frames:
            self.frames_integrated[frame.camera] = self.frames_integrated.get(frame.camera, 0) + 1

    def command(self, t: float, qdot: np.ndarray, plan: Plan | None) -> None:
        self.commands.append(CommandStamp(time.perf_counter(), t, (float(qdot[0]), float(qdot[1])), plan,
                                          threading.current_thread().name))

    def wall_at(self, t: float) -> float | None:
        """Wall time of the first physics step that reached robot time `t` (None: not in the history)."""
        steps = list(self.physics)
        if not steps or steps[0][0] > t:
            return None
        for sim_t, wall in steps:
            if sim_t + 1e-9 >= t:
                return wall
        return None
