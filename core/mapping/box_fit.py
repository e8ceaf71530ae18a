"""An upright box (centre, yaw, full extent) around an object's surface points: its published pose.

The footprint is the minimum-area rectangle of the points' x-y convex hull (rotating calipers), its
yaw chosen within ±45° of the frame the points are given in, so that refits in an object's own frame
do not flip the axes. The box reaches down to the floor when its lowest points are within
`floor_snap_m` of it (the floor filter removes the bottom few centimetres of every box).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import ConvexHull, QhullError


@dataclass(frozen=True)
class BoxFit:
    """Centre (3,), yaw (rad) and full extent (3,) of an upright box, in the points' frame."""

    centre: np.ndarray
    yaw: float
    extent: np.ndarray

    def pose(self) -> np.ndarray:
        """4×4 pose of the box centre."""
        T = np.eye(4)
        T[:3, :3] = self.rotation
        T[:3, 3] = self.centre
        return T

    @cached_property
    def rotation(self) -> np.ndarray:
        """3×3 rotation of the box axes (yaw about z)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    @cached_property
    def half(self) -> np.ndarray:
        """Half extent (3,)."""
        return self.extent / 2


def _hull(xy: np.ndarray) -> np.ndarray | None:
    """Vertices of the convex hull of xy (N×2), or None when degenerate."""
    try:
        return xy[ConvexHull(xy).vertices]
    except (QhullError, ValueError):
        return None


def min_area_yaw(xy: np.ndarray) -> float:
    """Yaw in [−π/4, π/4) of the minimum-area rectangle around points xy (N×2).

    Rotating calipers: the best rectangle has a side along an edge of the convex hull, and its
    extent along any direction is that of the hull's vertices.
    """
    hull = _hull(xy) if len(xy) >= 3 else None
    if hull is None:
        return 0.0
    edges = np.roll(hull, -1, axis=0) - hull
    angles = np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2)
    c, s = np.cos(angles), np.sin(angles)
    u = hull[:, 0, None] * c + hull[:, 1, None] * s
    v = -hull[:, 0, None] * s + hull[:, 1, None] * c
    area = (u.max(axis=0) - u.min(axis=0)) * (v.max(axis=0) - v.min(axis=0))
    yaw = float(angles[int(np.argmin(area))])
    return yaw - np.pi / 2 if yaw >= np.pi / 4 else yaw


def fit_upright_box(points: np.ndarray, floor_z: float | None = None, floor_snap_m: float = 0.0,
                    yaw: float | None = None) -> BoxFit:
    """Upright box around points (N×3); `floor_z` is the floor's height in the points' frame, if known.
    With `yaw` given only the extent is fitted (no hull)."""
    if yaw is None:
        yaw = min_area_yaw(points[:, :2])
    c, s = math.cos(yaw), math.sin(yaw)
    u = points[:, 0] * c + points[:, 1] * s
    v = -points[:, 0] * s + points[:, 1] * c
    lo = np.array([u.min(), v.min(), points[:, 2].min()])
    hi = np.array([u.max(), v.max(), points[:, 2].max()])
    if floor_z is not None and lo[2] - floor_z <= floor_snap_m:
        lo[2] = floor_z
    mid = (lo + hi) / 2
    centre = np.array([mid[0] * c - mid[1] * s, mid[0] * s + mid[1] * c, mid[2]])
    return BoxFit(centre=centre, yaw=yaw, extent=hi - lo)
