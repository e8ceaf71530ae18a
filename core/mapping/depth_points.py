"""Depth image → points in the world (docs/method.md, "Perception", step 1).

Vectorised pinhole unprojection: the unit-depth ray of every used pixel is computed once per
(intrinsics, image size, stride) and cached; a frame costs one multiply and one rigid transform.
Pixels with depth 0 (no return) or beyond the range cut-off are dropped. The per-pixel products run in
float32 (the depth image's precision); world points come out in float64.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from core.types import DepthFrame


@lru_cache(maxsize=16)
def _rays(K_bytes: bytes, height: int, width: int, stride: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera-frame rays (z = 1) of the pixels on a stride grid, and their pixel rows and columns."""
    K = np.frombuffer(K_bytes, dtype=float).reshape(3, 3)
    v, u = np.mgrid[0:height:stride, 0:width:stride]
    v, u = v.ravel(), u.ravel()
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    rays = np.stack([x, y, np.ones_like(x)], axis=1).astype(np.float32)
    rays.setflags(write=False)
    return rays, v, u


def pixel_rays(K: np.ndarray, shape: tuple[int, int], stride: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays (N×3, z = 1 in camera axes) through every `stride`-th pixel, with their rows v and columns u."""
    K = np.ascontiguousarray(K, dtype=float)
    return _rays(K.tobytes(), int(shape[0]), int(shape[1]), int(stride))


@dataclass(frozen=True)
class FramePoints:
    """World points (N×3) of one frame with their depth z (N,) and the world z of their rays at unit depth
    (N,): the floor filter's noise term needs both."""

    points: np.ndarray
    depth: np.ndarray
    ray_dz: np.ndarray


def unproject_frame(depth: np.ndarray, K: np.ndarray, T_world_camera: np.ndarray, stride: int = 1,
                    range_m: float = np.inf) -> FramePoints:
    """World points of the pixels with 0 < depth ≤ range_m on a `stride` pixel grid, with their depths.

    Depth is planar (along the optical axis, OpenCV camera axes: x right, y down, z forward).
    """
    rays, v, u = pixel_rays(K, depth.shape, stride)
    z = depth[v, u]
    keep = (z > 0.0) & (z <= range_m)
    z = z[keep]
    rays = rays[keep]
    R, t = T_world_camera[:3, :3].astype(np.float32), T_world_camera[:3, 3]
    points = ((rays * z[:, None]) @ R.T).astype(float) + t
    return FramePoints(points=points, depth=z.astype(float), ray_dz=(rays @ R[2]).astype(float))


def unproject(depth: np.ndarray, K: np.ndarray, T_world_camera: np.ndarray, stride: int = 1,
              range_m: float = np.inf) -> np.ndarray:
    """World points (N×3) of the pixels with 0 < depth ≤ range_m, on a `stride` pixel grid."""
    return unproject_frame(depth, K, T_world_camera, stride, range_m).points


def frame_points(frame: DepthFrame, stride: int = 4, range_m: float | None = None) -> np.ndarray:
    """Decimated world point cloud (N×3) of one depth frame, e.g. for drawing in the studio."""
    limit = frame.range_m if range_m is None else range_m
    return unproject(frame.depth, frame.K, frame.T_world_camera, stride, limit)
