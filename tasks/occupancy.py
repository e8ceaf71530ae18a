"""2D occupancy for base path planning, from the map's occupied points (any map kind)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy import ndimage

SUBCELLS = 3
"""Sub-cells per cell side for the inflation's distance (odd: a middle sub-cell sits on the cell's centre)."""


@dataclass(frozen=True)
class OccupancyGrid:
    """`blocked[i, j]` covers the cell at `origin + cell_m * (i + ½, j + ½)`; blocked cells are inflated."""

    origin: np.ndarray
    cell_m: float
    blocked: np.ndarray

    @classmethod
    def from_points(cls, points: np.ndarray, bounds: tuple[float, float, float, float], cell_m: float,
                    inflation_m: float, z_range_m: tuple[float, float] = (0.05, 2.0),
                    subcells: int = SUBCELLS) -> OccupancyGrid:
        """Cells whose centre lies within `inflation_m` of a point between the heights in `z_range_m`.

        The distance is measured on a grid `subcells` times finer (odd) whose middle sub-cell is centred on
        each cell's centre, so it is off by at most half a sub-cell's diagonal (2.4 cm with 3 at 0.1 m cells);
        `subcells=1`, a transform between the cells' centres, is off by up to half a cell's diagonal (7 cm)
        but costs a ninth: the sequencer uses it to notice a change and plans on the fine one."""
        x0, x1, y0, y1 = bounds
        shape = (max(1, int(np.ceil((x1 - x0) / cell_m))), max(1, int(np.ceil((y1 - y0) / cell_m))))
        origin = np.array([x0, y0], float)
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        pts = pts[(pts[:, 2] >= z_range_m[0]) & (pts[:, 2] <= z_range_m[1])]
        if inflation_m <= 0:
            return cls(origin, cell_m, _mark(pts[:, :2], origin, cell_m, shape))
        fine_m = cell_m / subcells
        fine = _mark(pts[:, :2], origin, fine_m, (shape[0] * subcells, shape[1] * subcells))
        if not fine.any():
            return cls(origin, cell_m, np.zeros(shape, bool))
        # only cells within reach of a point can be blocked: the transform runs on their block alone (the same
        # distances: every point lies inside it, and the transform is exact)
        reach = int(np.ceil(inflation_m / fine_m)) + 1
        marked = np.argwhere(fine)
        lo = np.maximum(0, (marked.min(axis=0) - reach) // subcells)
        hi = np.minimum(shape, (marked.max(axis=0) + reach) // subcells + 1)
        block = fine[lo[0] * subcells:hi[0] * subcells, lo[1] * subcells:hi[1] * subcells]
        middle = slice(subcells // 2, None, subcells)
        centres = cast(np.ndarray, ndimage.distance_transform_edt(~block))[middle, middle]
        blocked = np.zeros(shape, bool)
        blocked[lo[0]:hi[0], lo[1]:hi[1]] = centres * fine_m <= inflation_m
        return cls(origin, cell_m, blocked)

    def cell(self, xy: np.ndarray) -> tuple[int, int]:
        i, j = np.floor((np.asarray(xy, float) - self.origin) / self.cell_m).astype(int)
        return int(np.clip(i, 0, self.blocked.shape[0] - 1)), int(np.clip(j, 0, self.blocked.shape[1] - 1))

    def centre(self, cell: tuple[int, int]) -> np.ndarray:
        return self.origin + (np.asarray(cell, float) + 0.5) * self.cell_m

    def is_free(self, xy: np.ndarray) -> bool:
        return not self.blocked[self.cell(xy)]

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        """True if every cell along the straight segment a→b is free."""
        return bool(self.segments_free(a, np.asarray(b, float)[None])[0])

    def segments_free(self, a: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """For each row of `ends` (E×2), whether every cell along the straight segment from `a` to it is free.

        Each segment is sampled every half cell or closer, at the very points `np.linspace(a, end, n)` gives
        (its formula repeated: `k·step + a`, or `(k / div)·delta + a` where a component of the step is 0, and
        the end itself last), all segments in one batch."""
        a = np.asarray(a, float)
        ends = np.asarray(ends, float).reshape(-1, 2)
        delta = ends - a
        n = np.maximum(2, np.ceil(np.linalg.norm(delta, axis=1) / (0.5 * self.cell_m)).astype(int) + 1)
        segment = np.repeat(np.arange(len(n)), n)
        k = (np.arange(segment.size) - np.repeat(np.cumsum(n) - n, n)).astype(float)[:, None]
        div = (n - 1).astype(float)[:, None]
        step = delta / div
        flat = np.any(step == 0, axis=1)[segment, None]
        pts = np.where(flat, k / div[segment] * delta[segment], k * step[segment]) + a
        pts[np.cumsum(n) - 1] = ends
        idx = np.floor((pts - self.origin) / self.cell_m).astype(int)
        idx = np.clip(idx, 0, np.array(self.blocked.shape) - 1)
        hit = self.blocked[idx[:, 0], idx[:, 1]]
        return ~np.logical_or.reduceat(hit, np.cumsum(n) - n)

    def signature(self) -> int:
        """Cheap fingerprint: changes when the blocked set changes."""
        return hash(np.packbits(self.blocked).tobytes())




def _mark(xy: np.ndarray, origin: np.ndarray, cell_m: float, shape: tuple[int, int]) -> np.ndarray:
    """Cells (of `cell_m`, from `origin`) holding at least one of the points."""
    grid = np.zeros(shape, bool)
    idx = np.floor((xy - origin) / cell_m).astype(int)
    inside = np.all((idx >= 0) & (idx < shape), axis=1)
    grid[idx[inside, 0], idx[inside, 1]] = True
    return grid
