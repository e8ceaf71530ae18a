"""pydantic schema of a task sequence: an ordered list of base and end-effector subtasks.

Each subtask carries its target (a pose, or waypoints ending at one), tolerances, a timeout, a dwell
time (e.g. a pick-up) and the priority order of the HTMPC costs while it is active: [base, ee] for
navigation, [ee, base] for manipulation (docs/method.md, "The hierarchical-task MPC").
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Generic, Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

TaskName = Literal["base", "ee"]
Frame = Literal["world", "base"]
_Vec3 = tuple[float, float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)


class BasePose(_Strict):
    """Base target in the world: x, y (m) and an optional heading `yaw_deg` (None: position only)."""

    x: float
    y: float
    yaw_deg: float | None = None

    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])

    @property
    def yaw_rad(self) -> float | None:
        return None if self.yaw_deg is None else math.radians(self.yaw_deg)


class EEPose(_Strict):
    """End-effector target: `position` (m) and optional roll-pitch-yaw `rpy_deg` (None: position only), in the
    world or, with `frame: base`, in the base frame (x ahead, z up from the floor): held relative to the base
    wherever it drives."""

    position: _Vec3
    rpy_deg: _Vec3 | None = None
    frame: Frame = "world"

    def rotation(self) -> np.ndarray | None:
        """World rotation R_d (3×3) from rpy (fixed axes x, y, z), None when position only."""
        if self.rpy_deg is None:
            return None
        r, p, y = np.radians(self.rpy_deg)
        Rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
        Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        Rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        return Rz @ Ry @ Rx


class Tolerance(_Strict):
    """When a subtask counts as reached."""

    position_m: float = Field(default=0.1, gt=0.0)
    orientation_deg: float = Field(default=10.0, gt=0.0)


PoseT = TypeVar("PoseT", BasePose, EEPose)


class _SubtaskBase(_Strict, Generic[PoseT]):
    name: str = ""
    tolerance: Tolerance = Tolerance()
    timeout_s: float = Field(default=120.0, gt=0.0)
    dwell_s: float = Field(default=0.0, ge=0.0)
    """Time to hold the target within tolerance before the subtask completes (pick-up)."""
    priority: list[TaskName] | None = None
    """Order of the HTMPC costs while active; None: the kind's default."""
    if TYPE_CHECKING:  # each kind declares its own target and waypoints
        target: PoseT | None
        waypoints: list[PoseT]

    @field_validator("priority")
    @classmethod
    def _valid_priority(cls, v: list[TaskName] | None) -> list[TaskName] | None:
        if v is not None and (not v or len(set(v)) != len(v)):
            raise ValueError("priority lists 'base' and/or 'ee', each once")
        return v

    @model_validator(mode="after")
    def _has_goal(self):
        if self.target is None and not self.waypoints:
            raise ValueError("a subtask needs a target or waypoints")
        return self

    def goal(self) -> PoseT:
        """The final pose: the target, else the last waypoint."""
        return self.target if self.target is not None else self.waypoints[-1]

    def path(self) -> list[PoseT]:
        """Waypoints followed by the target."""
        return [*self.waypoints, *([self.target] if self.target is not None else [])]


class BaseSubtask(_SubtaskBase[BasePose]):
    """Drive the base to a pose, through optional waypoints (whole-body navigation).

    `ee` (frame: base) holds the hand at that pose relative to the base while it drives (the paper's
    navigation with the hand fixed beside the base); without it the hand stays at its ready pose, its
    camera looking ahead along the path."""

    kind: Literal["base"] = "base"
    target: BasePose | None = None
    waypoints: list[BasePose] = []
    ee: EEPose | None = None

    @field_validator("ee")
    @classmethod
    def _ee_in_base_frame(cls, v: EEPose | None) -> EEPose | None:
        if v is not None and v.frame != "base":
            raise ValueError("the hand pose held while driving is given in the base frame: add 'frame: base'")
        return v

    @property
    def order(self) -> list[TaskName]:
        return list(self.priority) if self.priority else ["base", "ee"]


class EESubtask(_SubtaskBase[EEPose]):
    """Bring the end effector to a pose (manipulation), through optional waypoints; in the base frame the base
    holds where it is and only the arm moves."""

    kind: Literal["ee"] = "ee"
    target: EEPose | None = None
    waypoints: list[EEPose] = []

    @model_validator(mode="after")
    def _one_frame(self):
        if len({p.frame for p in self.path()}) > 1:
            raise ValueError("target and waypoints of an EE subtask share one frame (all world or all base)")
        return self

    @property
    def frame(self) -> Frame:
        return self.goal().frame

    @property
    def order(self) -> list[TaskName]:
        return list(self.priority) if self.priority else ["ee", "base"]


Subtask = Annotated[BaseSubtask | EESubtask, Field(discriminator="kind")]


class TaskSequence(_Strict):
    """An ordered list of subtasks, run one after the other."""

    name: str = "sequence"
    scene: str | None = None
    """Optional scene file this sequence was written for (relative to the sequence file)."""
    subtasks: list[Subtask] = []
