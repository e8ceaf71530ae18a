"""Synthetic depth frames of axis-aligned rectangles (floor, walls, box faces), ray-cast exactly, and the
matching reference surfaces: registration geometry without a renderer."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.types import DepthFrame, ReferenceSurface

W, H, F = 160, 120, 110.0
K = np.array([[F, 0.0, W / 2], [0.0, F, H / 2], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Rect:
    """The rectangle axis = offset, lo ≤ the other two coordinates ≤ hi; `object_id` -2 is the floor."""

    axis: int
    offset: float
    lo: tuple[float, float]
    hi: tuple[float, float]
    object_id: int

    def moved(self, d: np.ndarray) -> Rect:
        others = [i for i in range(3) if i != self.axis]
        lo = tuple(self.lo[k] + d[o] for k, o in enumerate(others))
        hi = tuple(self.hi[k] + d[o] for k, o in enumerate(others))
        return Rect(self.axis, self.offset + d[self.axis], lo, hi, self.object_id)  # type: ignore[arg-type]

    def samples(self, step: float) -> np.ndarray:
        others = [i for i in range(3) if i != self.axis]
        a = np.arange(self.lo[0], self.hi[0] + 1e-9, step)
        b = np.arange(self.lo[1], self.hi[1] + 1e-9, step)
        ga, gb = np.meshgrid(a, b)
        pts = np.zeros((ga.size, 3))
        pts[:, self.axis] = self.offset
        pts[:, others[0]], pts[:, others[1]] = ga.ravel(), gb.ravel()
        return pts


FLOOR = Rect(2, 0.0, (-10.0, -10.0), (10.0, 10.0), -2)


def box(centre: tuple[float, float], size: float, object_id: int) -> list[Rect]:
    """The four vertical faces of an upright cube standing on the floor."""
    x, y, h = centre[0], centre[1], size / 2
    across_x = [Rect(0, x + s, (y - h, 0.0), (y + h, size), object_id) for s in (-h, h)]
    across_y = [Rect(1, y + s, (x - h, 0.0), (x + h, size), object_id) for s in (-h, h)]
    return across_x + across_y


def camera_pose(x: float, y: float, yaw: float, height: float = 0.5, pitch_deg: float = 15.0) -> np.ndarray:
    """T_world_camera (OpenCV axes) of a camera at (x, y, height) looking along yaw, pitched down."""
    p = math.radians(pitch_deg)
    fwd = np.array([math.cos(yaw) * math.cos(p), math.sin(yaw) * math.cos(p), -math.sin(p)])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    down = np.cross(fwd, right)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = right, down, fwd, (x, y, height)
    return T


def render(rects: list[Rect], T_world_camera: np.ndarray, t: float = 0.0, range_m: float = 3.0) -> DepthFrame:
    """The depth image of the rectangles from the camera (nearest hit; 0 where none within range)."""
    v, u = np.mgrid[0:H, 0:W]
    rays_c = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u, float)], axis=-1).reshape(-1, 3)
    R, o = T_world_camera[:3, :3], T_world_camera[:3, 3]
    rays = rays_c @ R.T
    best = np.full(len(rays), np.inf)
    for r in rects:
        others = [i for i in range(3) if i != r.axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (r.offset - o[r.axis]) / rays[:, r.axis]
            hit = o + s[:, None] * rays
        ok = (s > 0) & np.isfinite(s)
        for k, i in enumerate(others):
            ok &= (hit[:, i] >= r.lo[k]) & (hit[:, i] <= r.hi[k])
        best = np.where(ok & (s < best), s, best)
    depth = np.where(np.isfinite(best) & (best < range_m), best, 0.0).reshape(H, W)  # rays_c has z = 1
    return DepthFrame(t, "base", depth, K.copy(), T_world_camera, range_m)


def surface(rects: list[Rect], step: float = 0.05) -> ReferenceSurface:
    """The map's view of the non-floor rectangles."""
    parts = [(r.samples(step), r.object_id) for r in rects if r.object_id != -2]
    pts = np.vstack([p for p, _ in parts]) if parts else np.zeros((0, 3))
    ids = np.concatenate([np.full(len(p), i) for p, i in parts]) if parts else np.zeros(0, int)
    return ReferenceSurface(0.0, pts, ids.astype(int))
