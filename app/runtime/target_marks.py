"""The targets of a task sequence as plain marks for drawing (recordings, Foxglove): where each subtask's
waypoints and goal are, in the world or (EE targets with `frame: base`) in the base frame."""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.spatial.transform import Rotation

from tasks.schema import BasePose, EEPose, TaskSequence


@dataclass(frozen=True)
class TargetMark:
    """One waypoint or goal: `position` (m) in `frame` ("world" or "base"); `quaternion` (x, y, z, w) when the
    target has an orientation, else None; `goal` False for a waypoint."""

    index: int
    name: str
    kind: str
    frame: str
    position: tuple[float, float, float]
    quaternion: tuple[float, float, float, float] | None
    goal: bool


def _yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def _mark(index: int, name: str, pose: BasePose | EEPose, goal: bool) -> TargetMark:
    if isinstance(pose, BasePose):
        yaw = pose.yaw_rad
        return TargetMark(index, name, "base", "world", (pose.x, pose.y, 0.0),
                          None if yaw is None else _yaw_quaternion(yaw), goal)
    R = pose.rotation()
    quaternion = None if R is None else tuple(float(c) for c in Rotation.from_matrix(R).as_quat())
    return TargetMark(index, name, "ee", pose.frame, tuple(float(c) for c in pose.position),  # type: ignore[arg-type]
                      quaternion, goal)  # type: ignore[arg-type]


def target_marks(sequence: TaskSequence) -> tuple[TargetMark, ...]:
    """Every waypoint and goal of every subtask, in sequence order."""
    marks = []
    for index, subtask in enumerate(sequence.subtasks):
        path = subtask.path()
        marks += [_mark(index, subtask.name or f"{subtask.kind} {index + 1}", pose, k == len(path) - 1)
                  for k, pose in enumerate(path)]
    return tuple(marks)
