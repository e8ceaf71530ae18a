"""Anchored targets: poses given on a named mapped object, resolved into the world from what the map sees.

tasks/ reads the map only through `MapObjects`, a narrow typed view that app/ builds every control period
(app/object_names.py): per object its id, name, centre, yaw, extent, E[v] and status, and for each name that
has no object now, why ("box_3 not in the map", "box_3: 2 candidates", "box_3 not yet seen"). The yaw is
continuous since the name was bound (the box fit keeps yaw within ±45°, which would relabel the faces of a
turning box), and the extent is along the object's own axes at that yaw.

A mapped box is what the cameras saw of it: seen from one side, it is only as deep as the part of its top that
was seen, and its centre lies that much nearer the robot. So an anchored pose is placed from the faces the
cameras saw: along a horizontal axis where one side face was seen and the other not, and the box is mapped
shorter than its known size, it keeps the seen face and takes that size there (`ObjectView.size`: declared
with the name, or measured while both faces were seen); otherwise it is the map's box (`anchor_box`). The map
itself stays as it is, and conservative where nothing was seen (its completion, for collisions, is apart).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from tasks.schema import Anchor, BasePose, BaseSubtask, EEPose, EESubtask, Face

_FACE_AXES: dict[Face, tuple[int, float]] = {"top": (2, 1.0), "front": (0, -1.0), "back": (0, 1.0),
                                             "left": (1, 1.0), "right": (1, -1.0)}
"""Face → (axis, side) in the object's frame: front −x, back +x, left +y, right −y, top +z."""


@dataclass(frozen=True)
class ObjectView:
    """One mapped object as tasks/ sees it: centre `position` (m), `yaw` (rad), full `extent` (m) along its own
    axes, E[v] `consistency`, `status` ('active'); `sides_seen` (2×2 bool: axis x, y; −, + side) which side faces
    the cameras saw (None: all, e.g. a true box), `size` its known full size (3,) along its own axes (None:
    unknown)."""

    id: str
    name: str | None
    position: np.ndarray
    yaw: float
    extent: np.ndarray
    consistency: float = 1.0
    status: str = "active"
    sides_seen: np.ndarray | None = None
    size: np.ndarray | None = None


@dataclass(frozen=True)
class MapObjects:
    """The objects of the latest map snapshot at time `t`, and why a name has none (`unresolved`)."""

    t: float
    objects: tuple[ObjectView, ...] = ()
    unresolved: Mapping[str, str] = field(default_factory=dict)
    last_known: Mapping[str, np.ndarray] = field(default_factory=dict)
    """For a name in `unresolved`: where its object was last mapped, or where the sequence declared it (3, world)."""

    def named(self, name: str) -> ObjectView | None:
        return next((o for o in self.objects if o.name == name and o.status == "active"), None)

    def why_missing(self, name: str) -> str:
        return self.unresolved.get(name, f"{name} not yet seen")


def face_point(face: Face, extent: np.ndarray) -> np.ndarray:
    """Centre of `face` in the object's frame (m)."""
    axis, side = _FACE_AXES[face]
    p = np.zeros(3)
    p[axis] = side * float(extent[axis]) / 2.0
    return p


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def anchor_box(obj: ObjectView) -> tuple[np.ndarray, np.ndarray]:
    """Centre (3, world) and extent (3, own axes) of the box anchors are placed on: the map's box, except along a
    horizontal axis with one side face seen, mapped shorter than a known size, where the seen face stays and the
    box reaches the known size away from it (the unseen side's position is only as far as the top was seen).
    Mapped as long as its size or longer, the map's centre stays: a face seen at a grazing angle, or under an
    older odometry drift, lies a few centimetres off (measured 2.7 cm on the bench's box_a), and the far side
    was seen too."""
    centre = np.asarray(obj.position, float).copy()
    extent = np.asarray(obj.extent, float).copy()
    if obj.sides_seen is None or obj.size is None:
        return centre, extent
    shift = np.zeros(3)
    for a in (0, 1):
        minus, plus = bool(obj.sides_seen[a][0]), bool(obj.sides_seen[a][1])
        if minus == plus:
            continue
        size = float(obj.size[a])
        if not math.isfinite(size) or extent[a] >= size:
            continue  # seen over its whole size (or more: `unsettled`): the map's box is the better estimate
        shift[a] = (size - extent[a]) / 2 * (1.0 if minus else -1.0)  # away from the seen face
        extent[a] = size
    return centre + _rot_z(obj.yaw) @ shift, extent


def unsettled(obj: ObjectView, longer_m: float) -> str:
    """Why `obj` is not to be trusted for completing an anchored subtask now ('' if it is): mapped longer than its
    known size by more than `longer_m` along a horizontal axis (the map fused a moved box's old and new places
    into one long box). Shorter is expected where a side was not seen (`anchor_box` takes care of it); shorter
    with both sides seen was tried as a sign too and held picks that were 0.7-3 cm from the true box (bench)."""
    if obj.size is None:
        return ""
    extent = np.asarray(obj.extent, float)
    for a, axis in ((0, "x"), (1, "y")):
        size = float(obj.size[a])
        if math.isfinite(size) and extent[a] > size + longer_m:
            return f"{obj.name or obj.id} mapped {extent[a]:.2f} m along its {axis}, {size:.2f} m known: not settled"
    return ""


def settling(sub: BaseSubtask | EESubtask, objects: MapObjects | None, longer_m: float) -> str:
    """Why the subtask's anchored goal may not complete yet ('' when it may; `unsettled`)."""
    anchor = anchor_of(sub)
    obj = None if anchor is None or objects is None else objects.named(anchor.object)
    return "" if obj is None else unsettled(obj, longer_m)


def anchor_position(anchor: Anchor, obj: ObjectView) -> np.ndarray:
    """World position (3,) of the anchored point: box centre + R_z(yaw) (face centre + offset), on the box
    `anchor_box` places from the faces seen."""
    centre, extent = anchor_box(obj)
    local = face_point(anchor.face, extent) + np.asarray(anchor.offset, float)
    return centre + _rot_z(obj.yaw) @ local


def _world_rpy(anchor: Anchor, obj: ObjectView) -> tuple[float, float, float] | None:
    """rpy (deg, fixed axes) of the anchored rotation in the world: R_z(yaw) R(rpy) only adds yaw."""
    if anchor.rpy_deg is None:
        return None
    r, p, y = anchor.rpy_deg
    return (r, p, y + math.degrees(obj.yaw))


def resolve_pose(pose: BasePose | EEPose, objects: MapObjects | None) -> BasePose | EEPose | str:
    """The pose in the world (unchanged when not anchored), or why it cannot be placed now."""
    anchor = pose.anchor
    if anchor is None:
        return pose
    obj = None if objects is None else objects.named(anchor.object)
    if obj is None:
        return f"{anchor.object} not yet seen" if objects is None else objects.why_missing(anchor.object)
    p = anchor_position(anchor, obj)
    rpy = _world_rpy(anchor, obj)
    if isinstance(pose, BasePose):
        return BasePose(x=float(p[0]), y=float(p[1]), yaw_deg=None if rpy is None else rpy[2])
    return EEPose(position=(float(p[0]), float(p[1]), float(p[2])), rpy_deg=rpy)


def resolve_subtask(sub: BaseSubtask | EESubtask,
                    objects: MapObjects | None) -> tuple[BaseSubtask | EESubtask | None, str]:
    """The subtask with every anchored pose placed in the world, or (None, why not)."""
    if not is_anchored(sub):
        return sub, ""
    placed = [resolve_pose(p, objects) for p in sub.waypoints]
    target = None if sub.target is None else resolve_pose(sub.target, objects)
    why = next((r for r in [*placed, target] if isinstance(r, str)), None)
    if why is not None:
        return None, why
    return sub.model_copy(update={"waypoints": placed, "target": target}), ""


def is_anchored(sub: BaseSubtask | EESubtask) -> bool:
    return any(p.anchor is not None for p in sub.path())


def anchor_of(sub: BaseSubtask | EESubtask) -> Anchor | None:
    """The anchor of the subtask's goal (its target, else last waypoint), None when it is in the world."""
    return sub.goal().anchor


def describe(sub: BaseSubtask | EESubtask) -> str:
    """'top of box_3' for a subtask whose goal is anchored, '' otherwise (the subtask list shows it)."""
    anchor = anchor_of(sub)
    return "" if anchor is None else anchor.describe()
