"""A depth frame as the points registration uses: every stride-th pixel within range, in the world frame at the
frame's (predicted) camera pose."""

from __future__ import annotations

import numpy as np

from core.types import DepthFrame


def camera_points(frame: DepthFrame, stride_px: int, max_range_m: float) -> np.ndarray:
    """Points (P×3) in the camera frame (OpenCV axes) of every stride-th valid pixel closer than max_range_m."""
    depth = np.asarray(frame.depth)[::stride_px, ::stride_px]
    v, u = np.mgrid[0:frame.depth.shape[0]:stride_px, 0:frame.depth.shape[1]:stride_px]
    ok = np.isfinite(depth) & (depth > 0.0) & (depth < min(max_range_m, frame.range_m))
    z = depth[ok]
    K = frame.K
    x = (u[ok] - K[0, 2]) * z / K[0, 0]
    y = (v[ok] - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], axis=1)


def world_points(frame: DepthFrame, stride_px: int, max_range_m: float) -> np.ndarray:
    """`camera_points` moved to the world by the frame's T_world_camera."""
    pts = camera_points(frame, stride_px, max_range_m)
    T = frame.T_world_camera
    return pts @ T[:3, :3].T + T[:3, 3]


def in_view(points_world: np.ndarray, frame: DepthFrame, max_range_m: float) -> np.ndarray:
    """Mask of world points inside the frame's image and range (occlusion ignored)."""
    T = np.linalg.inv(frame.T_world_camera)
    c = points_world @ T[:3, :3].T + T[:3, 3]
    z = c[:, 2]
    front = (z > 0.1) & (z < min(max_range_m, frame.range_m))
    zs = np.where(front, z, 1.0)
    u = frame.K[0, 0] * c[:, 0] / zs + frame.K[0, 2]
    v = frame.K[1, 1] * c[:, 1] / zs + frame.K[1, 2]
    h, w = frame.depth.shape
    return front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
