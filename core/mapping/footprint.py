"""Footprint of an object: the x-y cells its surface voxels occupy in the object frame, with heights.

Touching boxes are one segment and so one object, and so are the shelf rows of an aisle, whose
corners join them into L- and ring-shaped objects. The upright box fitted around such an object
covers the corridor between its walls, so it must not stand for the object in the EDF, in the
association cost or in the Delta of the consistency update. `box_gap` says how far the fitted
box reaches beyond the seen surface: the largest distance from a point of the box's footprint to
the nearest occupied cell. A box seen from its front and one side has a gap about its own depth
(0.6 m for the paper's boxes); an L of two walls around a corridor has a gap of the corridor's
width and more. Objects with a gap under `box_fill_max_m` are boxes (solid in the EDF); the
others are their surface, each occupied column filled down to the floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy import ndimage

from core.mapping.box_fit import BoxFit


@dataclass(frozen=True)
class Footprint:
    """Occupied x-y cells of size `cell_m` (object frame), cell (0, 0) at `origin` (2,), and the highest
    surface point of each cell (`top`, −inf where empty)."""

    origin: np.ndarray
    cell_m: float
    top: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, cell_m: float) -> Footprint:
        """Footprint of object-frame points (N×3, N ≥ 1)."""
        cells = np.floor(points[:, :2] / cell_m).astype(np.int64)
        lo = cells.min(axis=0)
        k = cells - lo
        top = np.full(tuple(k.max(axis=0) + 1), -np.inf)
        np.maximum.at(top, (k[:, 0], k[:, 1]), points[:, 2])
        return cls(origin=lo * cell_m, cell_m=cell_m, top=top)

    @property
    def occupied(self) -> np.ndarray:
        return np.isfinite(self.top)

    def cell_centres(self) -> np.ndarray:
        """x-y centres (C×2) of the occupied cells."""
        return (np.argwhere(self.occupied) + 0.5) * self.cell_m + self.origin

    def box_gap(self, fit: BoxFit) -> float:
        """Largest distance (m) from the fitted box's footprint (sampled at `cell_m`) to an occupied cell.

        One 2D Euclidean distance transform of the free cells, on the footprint's grid grown to hold the box."""
        half = fit.half[:2]
        R = fit.rotation[:2, :2]
        corners = fit.centre[:2] + (np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]]) * half) @ R.T
        lo = np.floor(np.minimum(self.origin, corners.min(axis=0)) / self.cell_m).astype(int)
        hi = np.ceil(np.maximum(self.origin + self.cell_m * np.array(self.top.shape), corners.max(axis=0))
                     / self.cell_m).astype(int)
        free = np.ones(tuple(hi - lo + 1), dtype=bool)
        at = np.rint(self.origin / self.cell_m).astype(int) - lo
        occ = self.occupied
        free[at[0]:at[0] + occ.shape[0], at[1]:at[1] + occ.shape[1]] &= ~occ
        gap = cast(np.ndarray, ndimage.distance_transform_edt(free)) * self.cell_m
        n = np.maximum(np.ceil(2 * half / self.cell_m).astype(int), 1)
        u = (np.arange(n[0]) + 0.5) / n[0] * 2 * half[0] - half[0]
        v = (np.arange(n[1]) + 0.5) / n[1] * 2 * half[1] - half[1]
        uv = np.stack(np.meshgrid(u, v, indexing="ij"), axis=-1).reshape(-1, 2)
        k = np.floor((uv @ R.T + fit.centre[:2]) / self.cell_m).astype(int) - lo
        k = np.clip(k, 0, np.array(gap.shape) - 1)
        return float(gap[k[:, 0], k[:, 1]].max())

    def grown(self, grow_m: float) -> Footprint:
        """The footprint grown by `grow_m` sideways (square neighbourhood) and upwards."""
        g = int(np.ceil(grow_m / self.cell_m))
        top = np.pad(self.top, g, constant_values=-np.inf)
        top = ndimage.maximum_filter(top, size=2 * g + 1, mode="constant", cval=-np.inf)
        return Footprint(origin=self.origin - g * self.cell_m, cell_m=self.cell_m, top=top + grow_m)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Mask of object-frame points (N×3) over an occupied cell and not above its top."""
        k = np.floor((points[:, :2] - self.origin) / self.cell_m).astype(np.int64)
        ok = np.all((k >= 0) & (k < self.top.shape), axis=1)
        out = np.zeros(len(points), dtype=bool)
        out[ok] = points[ok, 2] <= self.top[k[ok, 0], k[ok, 1]]
        return out
