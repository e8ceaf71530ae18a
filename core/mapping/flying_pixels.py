"""Flying-pixel (jump-edge) filter: depth pixels at depth discontinuities are not used as points.

A real depth camera's pixels that straddle a depth edge read a depth between the two sides: points
hanging in free space behind an object's silhouette. Fused into the object they stretch its fitted
box away from the camera (figures in docs/decisions.md, "Flying-pixel filter"; the test of
`tests/core/mapping/test_map_objects.py` holds every side within 5 cm). Like the veil-point filters of
real pipelines, a used pixel is dropped when the depths returned in its 3 × 3 neighbourhood span more than

    jump_m + jump_per_m · z + 6 · c · z²

(the last term: the spread that depth noise of std c · z² gives nine pixels of one surface; the middle
one: a surface seen at a grazing angle up to ~80°). Both rims of a real edge go too: a pixel's width
(1.4 cm at 3 m) off each silhouette. Pixels without a return take no part.
"""

from __future__ import annotations

import numpy as np


def depth_span(depth: np.ndarray, stride: int) -> np.ndarray:
    """Max − min of the returning depths in the 3 × 3 neighbourhood of every `stride`-th pixel (rows, cols)."""
    h, w = depth.shape
    near = np.pad(np.where(depth > 0.0, depth, np.inf), 1, constant_values=np.inf)
    far = np.pad(depth, 1)
    hi = far[1:h + 1:stride, 1:w + 1:stride].copy()
    lo = near[1:h + 1:stride, 1:w + 1:stride].copy()
    for dv in (0, 1, 2):
        for du in (0, 1, 2):
            np.maximum(hi, far[dv:h + dv:stride, du:w + du:stride], out=hi)
            np.minimum(lo, near[dv:h + dv:stride, du:w + du:stride], out=lo)
    return np.where(np.isfinite(lo), hi - lo, 0.0)


def without_flying_pixels(depth: np.ndarray, stride: int, jump_m: float, jump_per_m: float,
                          noise_coeff_m: float) -> np.ndarray:
    """A copy of `depth` with the `stride`-th pixels at depth edges set to 0 (no return); others untouched."""
    out = np.array(depth, copy=True)
    d = out[::stride, ::stride]
    limit = jump_m + jump_per_m * d + 6.0 * noise_coeff_m * d**2
    d[depth_span(depth, stride) > limit] = 0.0
    return out
