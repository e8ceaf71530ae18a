"""One name per mapped object, the same in the 3D view, the plots, the status, the Names tab, the problems and the
recordings: the map's id ('#4'), followed by the operator's name for it where one was given ('#4 shelf')."""

from __future__ import annotations

from tasks.anchors import MapObjects

MAP_ID_PREFIX = "object_"
"""How tasks/ and the runtime's API spell a mapped object's id (`object_4`); the operator reads '#4'."""


def object_label(object_id: int, name: str | None = None) -> str:
    """'#4', or '#4 shelf' with the operator's `name`."""
    return f"#{object_id}" + (f" {name}" if name else "")


def object_id_of(map_object: int) -> str:
    """The id tasks/ and the API use for the map's object `map_object`: `object_4` for 4 (inverse of `map_id`)."""
    return f"{MAP_ID_PREFIX}{map_object}"


def map_id(object_id: str) -> int | None:
    """The map's id of an `object_<n>` id (None: a scene box id, as the ground-truth map names boxes)."""
    digits = object_id.removeprefix(MAP_ID_PREFIX)
    return int(digits) if object_id.startswith(MAP_ID_PREFIX) and digits.isdigit() else None


def shown_id(object_id: str) -> str:
    """What the operator reads for an object id: '#4' for `object_4`, a scene box id unchanged."""
    n = map_id(object_id)
    return object_label(n) if n is not None else object_id


def operator_names(objects: MapObjects | None) -> dict[int, str]:
    """The operator's names of mapped objects by map id, from the naming the sequencer saw last."""
    out: dict[int, str] = {}
    for o in () if objects is None else objects.objects:
        n = map_id(o.id)
        if n is not None and o.name:
            out[n] = o.name
    return out
