"""One name per mapped object, the same in the 3D view, the plots, the status and the recordings: the map's id
('#4'), followed by the operator's name for it where one was given ('#4 shelf')."""

from __future__ import annotations

from tasks.anchors import MapObjects

MAP_OBJECT_PREFIX = "object_"
"""How `app.object_names` names a map object to tasks/ (`object_4`); the ground-truth map's are box ids."""


def object_label(object_id: int, name: str | None = None) -> str:
    """'#4', or '#4 shelf' with the operator's `name`."""
    return f"#{object_id}" + (f" {name}" if name else "")


def names_by_map_id(anchors: MapObjects | None) -> dict[int, str]:
    """The operator's names bound to map objects now (`Snapshot.anchors`), by the map's object id."""
    if anchors is None:
        return {}
    return {int(o.id.removeprefix(MAP_OBJECT_PREFIX)): o.name for o in anchors.objects
            if o.name and o.id.startswith(MAP_OBJECT_PREFIX) and o.id.removeprefix(MAP_OBJECT_PREFIX).isdigit()}
