"""2D occupancy for base path planning, from the map's occupied points (any map kind)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class OccupancyGrid:
    """`blocked[i, j]` covers the cell at `origin + cell_m * (i + ½, j + ½)`; blocked cells are inflated."""

    origin: np.ndarray
    cell_m: float
    blocked: np.ndarray

    @classmethod
    def from_points(cls, points: np.ndarray, bounds: tuple[float, float, float, float], cell_m: float,
                    inflation_m: float, z_range_m: tuple[float, float] = (0.05, 2.0)) -> OccupancyGrid:
        """Cells holding any point between the heights in `z_range_m`, grown by `inflation_m`."""
        x0, x1, y0, y1 = bounds
        shape = (max(1, int(np.ceil((x1 - x0) / cell_m))), max(1, int(np.ceil((y1 - y0) / cell_m))))
        occupied = np.zeros(shape, bool)
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        pts = pts[(pts[:, 2] >= z_range_m[0]) & (pts[:, 2] <= z_range_m[1])]
        idx = np.floor((pts[:, :2] - [x0, y0]) / cell_m).astype(int)
        inside = np.all((idx >= 0) & (idx < shape), axis=1)
        occupied[idx[inside, 0], idx[inside, 1]] = True
        if inflation_m > 0 and occupied.any():
            blocked = cast(np.ndarray, ndimage.distance_transform_edt(~occupied)) * cell_m <= inflation_m
        else:
            blocked = occupied
        return cls(np.array([x0, y0], float), cell_m, blocked)

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
