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
        middle = slice(subcells // 2, None, subcells)
        centres = cast(np.ndarray, ndimage.distance_transform_edt(~fine))[middle, middle]
        return cls(origin, cell_m, centres * fine_m <= inflation_m)

    def cell(self, xy: np.ndarray) -> tuple[int, int]:
        i, j = np.floor((np.asarray(xy, float) - self.origin) / self.cell_m).astype(int)
        return int(np.clip(i, 0, self.blocked.shape[0] - 1)), int(np.clip(j, 0, self.blocked.shape[1] - 1))

    def centre(self, cell: tuple[int, int]) -> np.ndarray:
        return self.origin + (np.asarray(cell, float) + 0.5) * self.cell_m

    def is_free(self, xy: np.ndarray) -> bool:
        return not self.blocked[self.cell(xy)]

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        """True if every cell along the straight segment a→b is free."""
        n = max(2, int(np.ceil(np.linalg.norm(np.asarray(b) - a) / (0.5 * self.cell_m))) + 1)
        pts = np.linspace(a, b, n)
        idx = np.floor((pts - self.origin) / self.cell_m).astype(int)
        idx = np.clip(idx, 0, np.array(self.blocked.shape) - 1)
        return not self.blocked[idx[:, 0], idx[:, 1]].any()

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
