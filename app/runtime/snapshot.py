"""What the runtime publishes to its subscribers (the UI, the bridge, recorders): one frozen value.

Subscribers read snapshots only; they never reach into the controller or the map (docs/design.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from app.runtime.problems import ProblemCount
from app.runtime.target_marks import TargetMark
from core.localization import LocalizationHealth
from core.scene import Box
from core.types import DepthFrame, ObjectMapSnapshot, Plan, PoseSource, RobotState
from tasks.anchors import MapObjects
from tasks.sequencer import SubtaskProgress


class RunState(StrEnum):
    """What the runtime is doing with the active sequence."""

    IDLE = "idle"
    RUNNING = "running"
    PAUSED = "paused"
    FINISHED = "finished"
    FAILED = "failed"
    ESTOP = "emergency_stop"
    FAULT = "fault"
    """A loop raised or the robot state was not finite: the robot brakes along its last plan within the
    acceleration limits; Start is refused until Reset."""


@dataclass(frozen=True)
class EDFSlice:
    """A horizontal slice of the local EDF at height `z_m`: values[i, j] at origin + voxel·(i, j)."""

    origin: np.ndarray
    voxel: float
    z_m: float
    values: np.ndarray


@dataclass(frozen=True)
class Snapshot:
    """The studio's view of the world at sim time `state.t`."""

    seq: int
    wall_time: float
    state: RobotState
    run_state: RunState = RunState.IDLE
    status: str = ""
    boxes: tuple[Box, ...] = ()
    """Ground-truth boxes (simulation only)."""
    plan: Plan | None = None
    base_path: np.ndarray | None = None
    """The sequencer's planned base path (P×2)."""
    object_map: ObjectMapSnapshot | None = None
    map_points: np.ndarray | None = None
    """Occupied points of the map (decimated), for the voxel view."""
    edf_slice: EDFSlice | None = None
    clouds: np.ndarray | None = None
    """Decimated world points of the latest depth frame of each camera (for the point-cloud layer)."""
    progress: tuple[SubtaskProgress, ...] = ()
    active_index: int = -1
    sequence_version: int = 0
    min_distance_m: float = float("nan")
    collisions: int = 0
    timings_ms: dict[str, float] = field(default_factory=dict)
    map_kind: str = ""
    constraint: str = ""
    speed: float = 1.0
    messages: tuple[str, ...] = ()
    """Errors and warnings raised since the previous snapshot (shown as notifications)."""
    command: np.ndarray | None = None
    """The last joint velocity command sent to the robot (9,), None before the first."""
    depth_frames: tuple[DepthFrame, ...] = ()
    """The newest depth frame of each camera (recordings keep them on request)."""
    problems: tuple[ProblemCount, ...] = ()
    """Problems of the run so far, counted by kind (`app.runtime.problems`)."""
    fault: str | None = None
    """Why the run is in `RunState.FAULT` (kept until Reset), None without a fault."""
    targets: tuple[TargetMark, ...] = ()
    """Waypoints and goals of the sequence (for drawing in recordings and Foxglove)."""
    anchors: MapObjects | None = None
    """The named objects as the sequencer saw them at the last control step (None: no names)."""
    base_estimate: np.ndarray | None = None
    """The localizer's base pose estimate [x, y, yaw] in the world (`state.q[:3]`, the pose the controller
    drives), None without localization."""
    base_true: np.ndarray | None = None
    """The simulator's true base pose [x, y, yaw] when the state was observed (simulation only; what the robot
    does not know: with the sensor model's drifting odometry it differs from `state.q[:3]`)."""
    localization: LocalizationHealth | None = None
    """The pose estimate's health (`core/localization/health.py`): its covariance P and stds σ_xy, σ_yaw, the
    registrations accepted, rejected and degenerate so far, the age of the last accepted correction, the correction
    rate, why the pose is untrusted (None: trusted) and the margin the controller adds; None without localization."""
    pose_source: PoseSource = PoseSource.ODOMETRY
    """What the robot reports as its base pose: its odometry (corrected by the localizer with localization on) or a
    pose it localized itself (used as it is: the localizer is off for it, and `localization` is None)."""
