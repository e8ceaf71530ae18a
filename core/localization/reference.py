"""The reference registration aligns to: the floor (z = 0, a grid around the predicted base) and the trusted
surfaces the map exposes (`ReferenceSurface`), minus objects whose residuals disagreed lately."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from core.types import ReferenceSurface

FLOOR_ID = -2
"""Object id of the floor's points (the map's own ids are ≥ 0; -1 is an unlabelled surface)."""


@dataclass(frozen=True)
class Reference:
    """Reference points (P×3, world) and the object id of each (FLOOR_ID for the floor)."""

    points: np.ndarray
    object_ids: np.ndarray

    @property
    def object_points(self) -> int:
        """Points that are not floor."""
        return int(np.sum(self.object_ids != FLOOR_ID))


def floor_grid(centre_xy: np.ndarray, radius_m: float, step_m: float) -> np.ndarray:
    """Points of the floor z = 0 on a grid of pitch step_m within radius_m of centre_xy (on the world grid,
    so the same floor gives the same points wherever the robot is)."""
    lo = np.floor((np.asarray(centre_xy) - radius_m) / step_m) * step_m
    n = int(np.ceil(2 * radius_m / step_m)) + 1
    gx, gy = np.meshgrid(lo[0] + step_m * np.arange(n), lo[1] + step_m * np.arange(n))
    xy = np.stack([gx.ravel(), gy.ravel()], axis=1)
    xy = xy[np.hypot(*(xy - centre_xy).T) <= radius_m]
    return np.column_stack([xy, np.zeros(len(xy))])


def build(surface: ReferenceSurface | None, centre_xy: np.ndarray, radius_m: float, floor_step_m: float,
          excluded: Collection[int] = ()) -> Reference:
    """The floor plus the surface's points within radius_m of centre_xy, objects in `excluded` left out."""
    floor = floor_grid(centre_xy, radius_m, floor_step_m)
    if surface is None or len(surface.points) == 0:
        return Reference(floor, np.full(len(floor), FLOOR_ID))
    pts, ids = np.asarray(surface.points, float), np.asarray(surface.object_ids, int)
    keep = np.hypot(*(pts[:, :2] - centre_xy).T) <= radius_m
    if excluded:
        keep &= ~np.isin(ids, list(excluded))
    return Reference(np.vstack([floor, pts[keep]]), np.concatenate([np.full(len(floor), FLOOR_ID), ids[keep]]))
