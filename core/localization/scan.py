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


NEAR_M = 0.1
"""World points nearer than this (m, along the optical axis) are not in view."""


def project(points_world: np.ndarray, frame: DepthFrame, T_world_camera: np.ndarray, reach_m: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """World points in the frame's image with the camera at T_world_camera: their depth along the optical axis (m),
    pixel column and row (floored), and whether they lie in the image between `NEAR_M` and reach_m (occlusion
    ignored; the pixel is meaningless elsewhere)."""
    T = np.linalg.inv(T_world_camera)
    c = np.asarray(points_world, float) @ T[:3, :3].T + T[:3, 3]
    z = c[:, 2]
    front = (z > NEAR_M) & (z < reach_m)
    zs = np.where(front, z, 1.0)
    u = np.floor(frame.K[0, 0] * c[:, 0] / zs + frame.K[0, 2]).astype(int)
    v = np.floor(frame.K[1, 1] * c[:, 1] / zs + frame.K[1, 2]).astype(int)
    h, w = frame.depth.shape
    return z, u, v, front & (u >= 0) & (u < w) & (v >= 0) & (v < h)


def in_view(points_world: np.ndarray, frame: DepthFrame, max_range_m: float) -> np.ndarray:
    """Mask of world points inside the frame's image and range at its camera pose (occlusion ignored)."""
    return project(points_world, frame, frame.T_world_camera, min(max_range_m, frame.range_m))[3]
