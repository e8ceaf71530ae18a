"""Ground truth of the simulated scene: exact signed distance to the boxes, and an EDF grid of it.

The controller can run on this `LocalEDF` (the paper's "ground-truth map" runs); the mapping tests
compare their EDF against it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from core.scene import Box
from core.types import LocalEDF


def box_signed_distance(points: np.ndarray, box: Box) -> np.ndarray:
    """Exact signed distance (m) from points (..., 3) to a yawed box; negative inside."""
    p = np.asarray(points, dtype=float) - np.asarray(box.position)
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    local = np.stack([c * p[..., 0] + s * p[..., 1], -s * p[..., 0] + c * p[..., 1], p[..., 2]], axis=-1)
    q = np.abs(local) - np.asarray(box.size) / 2
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return outside + inside


def scene_signed_distance(points: np.ndarray, boxes: Iterable[Box], cutoff_m: float = np.inf) -> np.ndarray:
    """Signed distance to the nearest box, capped at `cutoff_m` (boxes farther than that are skipped)."""
    points = np.asarray(points, dtype=float)
    d = np.full(points.shape[:-1], cutoff_m, dtype=float)
    flat = points.reshape(-1, 3)
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    for box in boxes:
        r = 0.5 * float(np.linalg.norm(box.size))
        centre = np.asarray(box.position)
        if np.any(centre + r + cutoff_m < lo) or np.any(centre - r - cutoff_m > hi):
            continue
        d = np.minimum(d, box_signed_distance(points, box))
    return d


def ground_truth_edf(boxes: Iterable[Box], centre: np.ndarray, window_m: tuple[float, float, float] = (4.0, 4.0, 1.4),
                     voxel_m: float = 0.1, cutoff_m: float = 1.8, z_min_m: float = 0.0) -> LocalEDF:
    """Exact signed EDF on a grid of `window_m` around `centre` (x, y), from the floor up, truncated."""
    sizes = np.maximum(np.round(np.asarray(window_m) / voxel_m).astype(int) + 1, 2)
    origin = np.array([centre[0] - window_m[0] / 2, centre[1] - window_m[1] / 2, z_min_m])
    axes = [origin[i] + voxel_m * np.arange(sizes[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    values = np.minimum(scene_signed_distance(grid, boxes, cutoff_m), cutoff_m)
    return LocalEDF(origin=origin, voxel=voxel_m, values=values, cutoff=cutoff_m)
