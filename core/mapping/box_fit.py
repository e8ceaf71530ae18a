"""An upright box (centre, yaw, full extent) around an object's surface points: its published pose.

The footprint's yaw is that of the rectangle whose sides the points lie nearest (`box_yaw.py`), chosen
within ±45° of the frame the points are given in, so that refits in an object's own frame do not flip
the axes. The box reaches down to the floor when its lowest points are within
`floor_snap_m` of it (the floor filter removes the bottom few centimetres of every box).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from core.mapping.box_yaw import side_yaw

FACE_BAND_M = 0.15
"""Points within this of a fitted box's outermost point along a side's normal are that side face's points
(`_settle_faces`): wide enough for the depth noise at the 3 m range (± 2.5 σ), narrower than a box."""
MIN_FACE_POINTS = 5


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


def fit_upright_box(points: np.ndarray, floor_z: float | None = None, floor_snap_m: float = 0.0,
                    yaw: float | None = None) -> BoxFit:
    """Upright box around points (N×3); `floor_z` is the floor's height in the points' frame, if known.
    With `yaw` given only the extent is fitted (no hull)."""
    if yaw is None:
        yaw = side_yaw(points[:, :2])
    c, s = math.cos(yaw), math.sin(yaw)
    u = points[:, 0] * c + points[:, 1] * s
    v = -points[:, 0] * s + points[:, 1] * c
    lo = np.array([u.min(), v.min(), points[:, 2].min()])
    hi = np.array([u.max(), v.max(), points[:, 2].max()])
    _settle_faces(np.stack([u, v, points[:, 2]], axis=1), lo, hi)
    if floor_z is not None and lo[2] - floor_z <= floor_snap_m:
        lo[2] = floor_z
    mid = (lo + hi) / 2
    centre = np.array([mid[0] * c - mid[1] * s, mid[0] * s + mid[1] * c, mid[2]])
    return BoxFit(centre=centre, yaw=yaw, extent=hi - lo)


def _settle_faces(local: np.ndarray, lo: np.ndarray, hi: np.ndarray, band_m: float = FACE_BAND_M,
                  min_points: int = MIN_FACE_POINTS) -> None:
    """Move each side face of the box (lo, hi along x and y of the box frame, in place) from the outermost
    point to the mean of the points of that face: those within `band_m` of it, away from the other side faces
    by `band_m` and from the top and bottom faces (by `band_m`, or a quarter of the box's height if less).
    Depth noise spreads a face's points about it (σ = 0.005 z²: 4.5 cm at 3 m), so the outermost ones lie a
    few σ outside: min/max made every mapped box that much fatter. A face with fewer than `min_points` such
    points (not seen, or a box too small) keeps its outermost point."""
    if len(local) < min_points:
        return
    rim_z = min(band_m, (hi[2] - lo[2]) / 4)
    sides = (local[:, 2] < hi[2] - rim_z) & (local[:, 2] > lo[2] + rim_z)  # not the top or bottom face
    for a in (0, 1):
        b = 1 - a
        away = sides & (local[:, b] > lo[b] + band_m) & (local[:, b] < hi[b] - band_m)
        ends = (local[:, a] > hi[a] - band_m, local[:, a] < lo[a] + band_m)
        faces = [float(np.mean(local[away & end, a])) if np.sum(away & end) >= min_points else None for end in ends]
        if faces[0] is not None and faces[1] is not None and faces[0] < faces[1]:
            faces = [(faces[0] + faces[1]) / 2] * 2  # one face seen from both sides of a slab
        if faces[0] is not None:
            hi[a] = faces[0]
        if faces[1] is not None:
            lo[a] = faces[1]


def seen_sides(points: np.ndarray, fit: BoxFit, band_m: float = FACE_BAND_M,
               min_points: int = MIN_FACE_POINTS) -> np.ndarray:
    """Which side faces of the fitted box its surface points show (2×2 bool: axis x, y of the box; −, + side).

    A side is seen when at least `min_points` points lie within `band_m` of its plane, away from the other side
    faces and from the top and bottom rims (as `_settle_faces` picks a face's points). An unseen side's position
    in the fit is only the farthest surface seen there (often the edge of the top), not a face: a box seen from
    one side is as deep as the part of its top that was seen."""
    local = (np.asarray(points, float) - fit.centre) @ fit.rotation
    h = fit.half
    rim = min(band_m, h[2] / 2)
    sides = (local[:, 2] < h[2] - rim) & (local[:, 2] > -h[2] + rim)
    seen = np.zeros((2, 2), dtype=bool)
    for a in (0, 1):
        b = 1 - a
        away = sides & (np.abs(local[:, b]) < h[b] - band_m)
        for k, sign in enumerate((-1.0, 1.0)):
            seen[a, k] = int(np.sum(away & (np.abs(sign * local[:, a] - h[a]) <= band_m))) >= min_points
    return seen
