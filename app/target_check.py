"""Target checks (`tasks.validation`) against what a runtime knows of its scene: the simulated boxes, or
on a real robot the boxes of the object map. The studio, the bridge and the CLI call `check_targets`."""

from __future__ import annotations

import numpy as np

from app.object_label import object_label, shown_id
from core.params import HTMPCParams, SequencerParams
from core.types import ObjectMapSnapshot, ObjectStatus
from tasks.anchors import MapObjects
from tasks.schema import TaskSequence
from tasks.validation import (
    Obstacle,
    RobotEnvelope,
    Severity,
    TargetFinding,
    box_distance,
    check_sequence,
    require_valid,
)


def _mapped(object_map: ObjectMapSnapshot | None) -> tuple[Obstacle, ...]:
    """Live objects of an object map as boxes (id: the object's label, '#4')."""
    if object_map is None:
        return ()
    out = []
    for obj in object_map.objects:
        if obj.status == ObjectStatus.ACTIVE:
            R = obj.pose[:3, :3]
            out.append(Obstacle(object_label(obj.id), tuple(obj.pose[:3, 3]), tuple(obj.extent),
                                float(np.arctan2(R[1, 0], R[0, 0]))))
    return tuple(out)


def scene_obstacles(runtime) -> tuple[Obstacle, ...]:
    """Boxes of the simulated world, else the live objects of the runtime's map."""
    world = getattr(runtime, "world", None)
    if world is not None:
        return tuple(Obstacle(b.id, b.position, b.size, b.yaw) for b in world.boxes())
    return _mapped(runtime.snapshot().object_map)  # the snapshot reads the map under the map's lock


def snapshot_obstacles(snap) -> tuple[Obstacle, ...]:
    """The boxes a snapshot shows: the simulated ones, else the mapped ones."""
    if snap.boxes:
        return tuple(Obstacle(b.id, b.position, b.size, b.yaw) for b in snap.boxes)
    return _mapped(snap.object_map)


def nearest_obstacle(xy: np.ndarray, obstacles: tuple[Obstacle, ...]) -> str | None:
    """Id of the box whose footprint is nearest to xy (what a moved goal was moved away from)."""
    if not obstacles:
        return None
    d = [float(box_distance(o, np.asarray(xy, float)[:2])) for o in obstacles]
    return obstacles[int(np.argmin(d))].id


def obstacle_name(xy: np.ndarray, snap) -> str | None:
    """What the operator calls the obstacle nearest to xy: the mapped object's label ('#4') when the map has
    objects, with the simulated box there in brackets ('#4 (box_b)'); else the simulated box's id."""
    mapped = nearest_obstacle(xy, _mapped(snap.object_map))
    boxes = tuple(Obstacle(b.id, b.position, b.size, b.yaw) for b in snap.boxes)
    box = nearest_obstacle(xy, boxes)
    if mapped is None:
        return box
    return f"{mapped} ({box})" if box is not None else mapped


def envelope_of(runtime) -> RobotEnvelope:
    """The robot's envelope with the delta_safe the runtime's controller keeps."""
    htmpc = getattr(runtime.config, "htmpc", None) or HTMPCParams()
    sequencer = getattr(runtime.config, "sequencer", None) or SequencerParams()
    return RobotEnvelope.of(runtime.robot, htmpc.delta_safe_m, base_clearance_m=sequencer.inflation_m)


def check_targets(runtime, sequence: TaskSequence, *, scene_may_change: bool = False,
                  indices: list[int] | None = None, source: str = "sequence",
                  text: str | None = None) -> list[TargetFinding]:
    """`tasks.validation.require_valid` in the runtime's scene: raises `TargetError`, returns the warnings.

    In simulation the scene is known, so base goals no path reaches from where the robot stands are refused
    too; on a real robot the map is partial (a gap not seen yet may be there), so they are not."""
    start = None
    if getattr(runtime, "world", None) is not None:
        start = np.asarray(runtime.state.q[:2], float)
    return require_valid(sequence, scene_obstacles(runtime), envelope_of(runtime), scene_may_change=scene_may_change,
                         indices=indices, source=source, text=text, start_xy=start,
                         planner=getattr(runtime.config, "sequencer", None),
                         anchors=anchor_boxes(runtime, sequence))


def named_boxes(objects: MapObjects | None) -> dict[str, Obstacle]:
    """The named objects of a map view as boxes, by name (with their faces' yaw and extent)."""
    if objects is None:
        return {}
    return {o.name: Obstacle(shown_id(o.id), (float(o.position[0]), float(o.position[1]), float(o.position[2])),
                             (float(o.extent[0]), float(o.extent[1]), float(o.extent[2])), float(o.yaw))
            for o in objects.objects if o.name is not None}


def anchor_boxes(runtime, sequence: TaskSequence) -> dict[str, Obstacle]:
    """Name → the box an anchored target sits on now: the map's object bound to the name, else (simulation)
    the scene box of that id."""
    world = getattr(runtime, "world", None)
    scene = {} if world is None else {b.id: Obstacle(b.id, b.position, b.size, b.yaw) for b in world.boxes()}
    loop = getattr(runtime, "closed_loop", None)
    mapped = named_boxes(getattr(loop, "objects_view", None))
    return {name: mapped.get(name) or scene[name] for name in sequence.objects if name in mapped or name in scene}


def recheck_anchored(loop, sequence: TaskSequence, index: int, objects: MapObjects | None) -> list[str]:
    """Subtask `index`'s anchored targets checked again where their objects are now (after a move), against
    every object the map sees: the reasons of the rules they break (`loop`: the closed loop, its robot and
    configuration)."""
    if objects is None or index >= len(sequence.subtasks):
        return []
    obstacles = tuple(Obstacle(shown_id(o.id), (float(o.position[0]), float(o.position[1]), float(o.position[2])),
                               (float(o.extent[0]), float(o.extent[1]), float(o.extent[2])), float(o.yaw))
                      for o in objects.objects)
    findings = check_sequence(sequence, obstacles, envelope_of(loop), indices=[index], anchors=named_boxes(objects))
    return [f"subtask {index + 1}: {f.message} (its object moved)" for f in findings if f.severity == Severity.ERROR]
