"""pydantic schema of a task sequence: an ordered list of base and end-effector subtasks.

Each subtask carries its target (a pose, or waypoints ending at one), tolerances, a timeout, a dwell
time (e.g. a pick-up) and the priority order of the HTMPC costs while it is active: [base, ee] for
navigation, [ee, base] for manipulation (docs/method.md, "The hierarchical-task MPC").
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Generic, Literal, TypeVar

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PositiveFloat,
    SerializerFunctionWrapHandler,
    ValidationError,
    field_validator,
    model_serializer,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

TaskName = Literal["base", "ee"]
Frame = Literal["world", "base"]
Face = Literal["top", "front", "back", "left", "right"]
FACES: tuple[Face, ...] = ("top", "front", "back", "left", "right")
ObjectName = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$")]
"""A name the operator gives a mapped object (or a simulated scene box's id): a letter or '_', then letters,
digits, '_', '.', '-'."""
_Vec3 = tuple[float, float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)


class Anchor(_Strict):
    """A pose given relative to a named mapped object instead of the world, in the object's own frame (box
    centre, its yaw; x toward its back, y toward its left, z up): the centre of `face` plus `offset` (m), turned
    by `rpy_deg` (fixed axes, relative to the object's yaw; None: position only). front = the −x face, back +x,
    left +y, right −y, top +z (docs/design.md, "Anchored targets")."""

    object: ObjectName
    face: Face = "top"
    offset: _Vec3 = (0.0, 0.0, 0.0)
    rpy_deg: _Vec3 | None = None

    def describe(self) -> str:
        """'top of box_3' (with the offset when it is not zero)."""
        off = "" if not any(self.offset) else f" + ({', '.join(f'{v:g}' for v in self.offset)})"
        return f"{self.face} of {self.object}{off}"


def _require_unanchored(title: str, data, keys: tuple[str, ...]):
    """Without an anchor, the coordinates are required (pydantic's own 'missing' error at each key)."""
    if isinstance(data, dict) and data.get("anchor") is None:
        missing = [InitErrorDetails(type="missing", loc=(k,), input=data) for k in keys if k not in data]
        if missing:
            raise ValidationError.from_exception_data(title, missing)
    return data


class _Placed(_Strict):
    """A pose given in coordinates or by an anchor; an anchored one is written (dumped) as its anchor alone,
    so that what is written reads back."""

    anchor: Anchor | None = None

    @model_serializer(mode="wrap")
    def _anchor_alone(self, handler: SerializerFunctionWrapHandler):
        data = handler(self)
        if self.anchor is not None and isinstance(data, dict):
            return {k: v for k, v in data.items() if k in ("anchor",)}
        return data


def _refuse_with_anchor(data, keys: tuple[str, ...], what: str):
    """An anchored pose takes its place from its anchor: world coordinates beside it are a mistake."""
    if isinstance(data, dict) and data.get("anchor") is not None:
        given = [k for k in keys if data.get(k) is not None]
        if given:
            raise ValueError(f"an anchored {what} takes its place from the anchor: drop {', '.join(given)}")
    return data


class BasePose(_Placed):
    """Base target in the world: x, y (m) and an optional heading `yaw_deg` (None: position only)."""

    x: float = 0.0
    y: float = 0.0
    yaw_deg: float | None = None
    """Relative to a named object (x, y, yaw_deg then left out); the sequencer resolves it every period."""

    @model_validator(mode="before")
    @classmethod
    def _place(cls, data):
        data = _refuse_with_anchor(data, ("x", "y", "yaw_deg"), "base pose")
        return _require_unanchored(cls.__name__, data, ("x", "y"))

    @field_validator("anchor")
    @classmethod
    def _heading_only(cls, v: Anchor | None) -> Anchor | None:
        if v is not None and v.rpy_deg is not None and (v.rpy_deg[0] or v.rpy_deg[1]):
            raise ValueError("a base pose turns only about z: rpy_deg is [0, 0, yaw]")
        return v

    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])

    @property
    def yaw_rad(self) -> float | None:
        return None if self.yaw_deg is None else math.radians(self.yaw_deg)


class EEPose(_Placed):
    """End-effector target: `position` (m) and optional roll-pitch-yaw `rpy_deg` (None: position only), in the
    world or, with `frame: base`, in the base frame (x ahead, z up from the floor): held relative to the base
    wherever it drives."""

    position: _Vec3 = (0.0, 0.0, 0.0)
    rpy_deg: _Vec3 | None = None
    frame: Frame = "world"

    @model_validator(mode="before")
    @classmethod
    def _place(cls, data):
        data = _refuse_with_anchor(data, ("position", "rpy_deg"), "EE pose")
        if isinstance(data, dict) and data.get("anchor") is not None and data.get("frame", "world") != "world":
            raise ValueError("an anchored EE pose is in the object's frame: drop 'frame: base'")
        return _require_unanchored(cls.__name__, data, ("position",))

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


class NamedObject(_Strict):
    """A name for a mapped object: where the operator saw it when naming it (world, m; None: a simulated scene
    box's id, bound where the box is). A new run binds the name to the mapped object nearest there. `size`: its
    full size (m) along its x, y, z if known (x and y either way round): anchors on it are then placed from the
    faces the cameras saw, where the map has seen it from one side only (docs/design.md, "Anchored targets")."""

    position: _Vec3 | None = None
    yaw_deg: float = 0.0
    size: tuple[PositiveFloat, PositiveFloat, PositiveFloat] | None = None


class TaskSequence(_Strict):
    """An ordered list of subtasks, run one after the other."""

    name: str = "sequence"
    scene: str | None = None
    """Optional scene file this sequence was written for (relative to the sequence file)."""
    objects: dict[ObjectName, NamedObject] = {}
    """Names of mapped objects the anchored targets refer to (saved with the sequence)."""
    subtasks: list[Subtask] = []

    @model_validator(mode="after")
    def _anchors_named(self):
        known = ", ".join(self.objects) or "none"
        errors = [InitErrorDetails(type=PydanticCustomError(
                      "unknown_object", "unknown object '{name}': name it under 'objects' first (named: {known})",
                      {"name": a.object, "known": known}),
                      loc=(*field, "anchor", "object"), input=a.object)
                  for field, a in anchored_poses(self) if a.object not in self.objects]
        if errors:
            raise ValidationError.from_exception_data("TaskSequence", errors)
        return self


def anchored_poses(sequence: TaskSequence) -> list[tuple[tuple[str | int, ...], Anchor]]:
    """(field location, anchor) of every anchored target and waypoint, in order."""
    out: list[tuple[tuple[str | int, ...], Anchor]] = []
    for i, sub in enumerate(sequence.subtasks):
        for k, w in enumerate(sub.waypoints):
            if w.anchor is not None:
                out.append((("subtasks", i, "waypoints", k), w.anchor))
        if sub.target is not None and sub.target.anchor is not None:
            out.append((("subtasks", i, "target"), sub.target.anchor))
    return out


def anchored_on(sequence: TaskSequence, name: str) -> list[int]:
    """The subtasks (numbered from 1) with a target or waypoint anchored on the object `name`."""
    return sorted({int(loc[1]) + 1 for loc, a in anchored_poses(sequence) if a.object == name})
