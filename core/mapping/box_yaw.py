"""Yaw of an upright box from its surface points: the rectangle whose sides the points lie on.

A box's seen surface, looked at from above, lies on the sides of its footprint rectangle. The yaw here
minimises the mean distance of the points (x-y) to the nearest side of their bounding rectangle in that yaw
(the "closeness" criterion of L-shape fitting to laser scans, Zhang et al., IV 2017), searched over
[−45°, 45°) every `COARSE_RAD` and refined around the best every `FINE_RAD`.

It replaces the minimum-area rectangle (rotating calipers), which is ambiguous for the L that two seen faces
of a square box make: the rectangle along the faces (a · a) and the one along the L's diagonal (a√2 · a/√2)
have the same area, and depth noise (4.5 cm at 3 m) tips it to the diagonal, 45° off. On the paper's random
scenes that put boxes seen across a corner 41–44° off; such a box reaches into free space beside the real one
(a camera that then sees free space inside it makes it "hollow" for good) and misses its corners
(docs/decisions.md, "Box yaw from the sides the points lie on"). Along the faces the points lie on two sides;
along the diagonal they cross the rectangle's inside.

The points are merged into x-y cells of `CELL_M` first (a cell's mean, weighted by its count): a side face's
points stack in columns, so this divides the work by about the face's height in voxels.
"""

from __future__ import annotations

import numpy as np

COARSE_RAD = np.radians(1.0)
"""Step (rad) of the first search over [−45°, 45°)."""
FINE_RAD = np.radians(0.1)
"""Step (rad) of the refinement within ±`COARSE_RAD` of the best coarse yaw."""
CELL_M = 0.025
"""Points are merged into x-y cells of this size (m) before the search."""


def mean_side_distance(xy: np.ndarray, weight: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """Weighted mean distance (m) of points xy (N×2) to the nearest side of their bounding rectangle at each
    yaw (M,) → (M,)."""
    c, s = np.cos(yaws)[None, :], np.sin(yaws)[None, :]
    u = xy[:, :1] * c + xy[:, 1:] * s
    v = -xy[:, :1] * s + xy[:, 1:] * c
    du = np.minimum(u.max(axis=0) - u, u - u.min(axis=0))
    dv = np.minimum(v.max(axis=0) - v, v - v.min(axis=0))
    return (np.minimum(du, dv) * weight[:, None]).sum(axis=0) / weight.sum()


def merge_cells(xy: np.ndarray, cell_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean point (K×2) and point count (K,) of each occupied x-y cell."""
    keys = np.floor(xy / cell_m).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    means = np.stack([np.bincount(inverse, xy[:, a]) for a in range(2)], axis=1) / counts[:, None]
    return means, counts.astype(float)


def side_yaw(xy: np.ndarray, cell_m: float = CELL_M) -> float:
    """Yaw in [−π/4, π/4) of the rectangle whose sides the points xy (N×2) lie nearest (0 for fewer than 3)."""
    if len(xy) < 3:
        return 0.0
    points, weight = merge_cells(np.asarray(xy, float), cell_m)
    coarse = np.arange(-np.pi / 4, np.pi / 4, COARSE_RAD)
    best = coarse[int(np.argmin(mean_side_distance(points, weight, coarse)))]
    fine = best + np.arange(-COARSE_RAD, COARSE_RAD + 1e-12, FINE_RAD)
    yaw = float(fine[int(np.argmin(mean_side_distance(points, weight, fine)))])
    return (yaw + np.pi / 4) % (np.pi / 2) - np.pi / 4
