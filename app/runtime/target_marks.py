"""The targets of a task sequence as plain marks for drawing (recordings, Foxglove): where each subtask's
waypoints and goal are, in the world or (EE targets with `frame: base`) in the base frame. An anchored pose
is relative to its object, so it is drawn only where the sequencer has placed it on the object (the goal's
`SubtaskProgress.anchored_goal`), never at its raw offset as if that were a world position."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from scipy.spatial.transform import Rotation

from tasks.schema import BasePose, EEPose, TaskSequence
from tasks.sequencer import SubtaskProgress


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


def _placed(pose: BasePose | EEPose, at: tuple[float, float, float]) -> BasePose | EEPose:
    """An anchored pose where the sequencer placed it (orientation left out: it follows the object's yaw)."""
    if isinstance(pose, BasePose):
        return BasePose(x=at[0], y=at[1])
    return EEPose(position=at)


def target_marks(sequence: TaskSequence, progress: Sequence[SubtaskProgress] = ()) -> tuple[TargetMark, ...]:
    """Every waypoint and goal of every subtask, in sequence order; anchored ones only once `progress` holds
    where their goal sits on its object."""
    placed = {p.index: p.anchored_goal for p in progress if p.anchored_goal is not None}
    marks = []
    for index, subtask in enumerate(sequence.subtasks):
        path = subtask.path()
        name = subtask.name or f"{subtask.kind} {index + 1}"
        for k, pose in enumerate(path):
            goal = k == len(path) - 1
            if pose.anchor is None:
                marks.append(_mark(index, name, pose, goal))
            elif goal and index in placed:
                marks.append(_mark(index, name, _placed(pose, placed[index]), goal))
    return tuple(marks)
