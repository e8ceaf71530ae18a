"""One name per mapped object, the same in the 3D view, the plots, the status and the recordings: the map's id
('#4'), followed by the operator's name for it where one was given ('#4 shelf')."""

from __future__ import annotations


def object_label(object_id: int, name: str | None = None) -> str:
    """'#4', or '#4 shelf' with the operator's `name`."""
    return f"#{object_id}" + (f" {name}" if name else "")
