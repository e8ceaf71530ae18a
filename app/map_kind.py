"""The kinds of map the runtime can give the controller (a light module: the bridge's protocol uses it)."""

from __future__ import annotations

import typing
from typing import Literal

MapKind = Literal["object", "voxel", "ground_truth"]
"""POCD's object map, the static-world voxel baseline, or the simulation's ground truth."""
MAP_KINDS: tuple[MapKind, ...] = typing.get_args(MapKind)
