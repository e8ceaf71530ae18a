"""Target checks (`tasks.validation`) against what a runtime knows of its scene: the simulated boxes, or
on a real robot the boxes of the object map. The studio, the bridge and the CLI call `check_targets`."""

from __future__ import annotations

import numpy as np

from core.params import HTMPCParams
from core.types import ObjectStatus
from tasks.schema import TaskSequence
from tasks.validation import Obstacle, RobotEnvelope, TargetFinding, require_valid


def scene_obstacles(runtime) -> tuple[Obstacle, ...]:
    """Boxes of the simulated world, else the live objects of the runtime's map (id `object_<n>`)."""
    world = getattr(runtime, "world", None)
    if world is not None:
        return tuple(Obstacle(b.id, b.position, b.size, b.yaw) for b in world.boxes())
    object_map = runtime.snapshot().object_map  # the runtime's snapshot reads its map under the map's lock
    if object_map is None:
        return ()
    out = []
    for obj in object_map.objects:
        if obj.status != ObjectStatus.ACTIVE:
            continue
        R = obj.pose[:3, :3]
        out.append(Obstacle(f"object_{obj.id}", tuple(obj.pose[:3, 3]), tuple(obj.extent),
                            float(np.arctan2(R[1, 0], R[0, 0]))))
    return tuple(out)


def envelope_of(runtime) -> RobotEnvelope:
    """The robot's envelope with the delta_safe the runtime's controller keeps."""
    htmpc = getattr(runtime.config, "htmpc", None) or HTMPCParams()
    return RobotEnvelope.of(runtime.robot, htmpc.delta_safe_m)


def check_targets(runtime, sequence: TaskSequence, *, scene_may_change: bool = False,
                  indices: list[int] | None = None, source: str = "sequence",
                  text: str | None = None) -> list[TargetFinding]:
    """`tasks.validation.require_valid` in the runtime's scene: raises `TargetError`, returns the warnings."""
    return require_valid(sequence, scene_obstacles(runtime), envelope_of(runtime), scene_may_change=scene_may_change,
                         indices=indices, source=source, text=text)
