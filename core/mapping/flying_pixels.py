"""Flying-pixel (jump-edge) filter: depth pixels at depth discontinuities are not used as points.

A real depth camera's pixels that straddle a depth edge read a depth between the two sides: points
hanging in free space behind an object's silhouette. Fused into the object they stretch its fitted
box away from the camera (figures in docs/decisions.md, "Flying-pixel filter"; the test of
`tests/core/mapping/test_map_objects.py` holds every side within 5 cm). Like the veil-point filters of
real pipelines, a pixel is mixed, and dropped, when either test fails:

- **span**: the depths returned in its 3 × 3 neighbourhood span more than
  jump_m + jump_per_m · z + 6 · c · z² (the last term: the spread that depth noise of std c · z² gives
  nine pixels of one surface; the middle one: a surface seen at a grazing angle up to ~80°). Both rims of
  a real edge go too: a pixel's width (1.4 cm at 3 m) off each silhouette.
- **support**, for a pixel with a silent neighbour and a nearer one (beyond the same tolerance): fewer than
  `min_support` of its 8 neighbours return a depth within 3√2 · c · z² + slope · z of its own. The span test
  is blind where the far side of the edge returns nothing (a background beyond the range): a mixed pixel there
  reads up to the range behind the near side, and a span of a few tens of centimetres passes the noise term at
  2–3 m. Its neighbours are the near side (too near), silent pixels and other mixed pixels at their own random
  depths, so it has no surface around it; a pixel of a real surface has 3 (a box's corner) to 8 such
  neighbours. Where every neighbour returns, the span test has seen the edge, and this one is not asked: a
  face seen at a grazing angle (a box's side a few pixels wide) would lose the points that register the box
  when it is pushed. Nor where no neighbour is nearer: the rim of the near side itself (a box's corner against
  the far floor) is a surface, and dropping it changed which vacated places E1's object map cleared (one
  scene: 1 → 4 phantoms).

Pixels without a return take no part. The same tests run on a strided frame (the points) and on scattered
pixels (the visibility checks), so a pixel left out of the points is no evidence there either.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.params import MappingParams


@dataclass(frozen=True)
class EdgeFilter:
    """The two tests' settings (`MappingParams.flying_pixel_*` and `depth_noise_coeff_m`)."""

    jump_m: float
    jump_per_m: float
    noise_coeff_m: float
    min_support: int
    slope: float

    @classmethod
    def of(cls, params: MappingParams) -> EdgeFilter:
        p = params
        return cls(p.flying_pixel_jump_m, p.flying_pixel_jump_per_m, p.depth_noise_coeff_m,
                   p.flying_pixel_min_support, p.flying_pixel_support_slope)

    def span_limit(self, depth: np.ndarray) -> np.ndarray:
        """Largest 3 × 3 depth span (m) of one surface at this depth."""
        return self.jump_m + self.jump_per_m * depth + 6.0 * self.noise_coeff_m * depth**2

    def neighbour_tol(self, depth: np.ndarray) -> np.ndarray:
        """Largest depth difference (m) of two neighbouring pixels of one surface at this depth."""
        return 3.0 * np.sqrt(2.0) * self.noise_coeff_m * depth**2 + self.slope * depth

    def mixed(self, depth: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
        """Is each pixel of `depth` (…) mixed, given its 3 × 3 neighbourhood `neighbours` (9, …; centre 5th)?

        The neighbour axis comes first: the reductions over it then run element-wise over whole contiguous
        images (over a trailing axis of 9 they took a quarter of the mapping stage's time)."""
        returning = neighbours > 0.0
        hi = neighbours.max(axis=0)
        lo = np.where(returning, neighbours, np.inf).min(axis=0)
        span = np.where(np.isfinite(lo), hi - lo, 0.0)
        mixed = span > self.span_limit(depth)
        if self.min_support > 0:
            # only where a neighbour is silent (with every neighbour returning, the span test has seen the edge)
            # and a nearer one returns: a mixed pixel hangs behind the near side; a rim pixel of the near side
            # itself, or a surface beside a dropout, has no nearer neighbour beyond the tolerance
            tol = self.neighbour_tol(depth)
            same = returning & (np.abs(neighbours - depth) <= tol)
            lonely = same.sum(axis=0) - 1 < self.min_support  # the centre pixel is always its own neighbour
            behind = depth - lo > tol
            mixed |= lonely & behind & ~returning.all(axis=0)
        return mixed & (depth > 0.0)


def neighbourhoods(depth: np.ndarray, stride: int) -> np.ndarray:
    """The 3 × 3 neighbourhood of every `stride`-th pixel (9, rows, cols), 0 outside the image."""
    h, w = depth.shape
    pad = np.pad(depth, 1)
    return np.stack([pad[dv:h + dv:stride, du:w + du:stride] for dv in (0, 1, 2) for du in (0, 1, 2)])


def neighbourhoods_at(depth: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The 3 × 3 neighbourhood of the pixels (v, u) (9, N), 0 outside the image."""
    h, w = depth.shape
    off = np.arange(-1, 2)
    vv = (v[None, None, :] + off[:, None, None]).repeat(3, axis=1)
    uu = (u[None, None, :] + off[None, :, None]).repeat(3, axis=0)
    inside = (vv >= 0) & (vv < h) & (uu >= 0) & (uu < w)
    d = depth[np.clip(vv, 0, h - 1), np.clip(uu, 0, w - 1)]
    return np.where(inside, d, 0.0).reshape(9, len(v))


def without_flying_pixels(depth: np.ndarray, stride: int, edges: EdgeFilter) -> np.ndarray:
    """A copy of `depth` with the `stride`-th pixels that are mixed set to 0 (no return); others untouched."""
    out = np.array(depth, copy=True)
    d = out[::stride, ::stride]
    d[edges.mixed(d, neighbourhoods(depth, stride))] = 0.0
    return out
