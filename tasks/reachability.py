"""Which base positions a path can reach from the robot's start, on a scene that is known (the boxes of the
simulation, or the mapped ones): the free cells of the planner's grid connected to the start's.

The grid is the one A* searches (`SequencerParams.plan_bounds_m`, `grid_cell_m`), a cell blocked where its
centre is closer than the base clearance (`inflation_m`) to a box footprint. A* moves only between free cells
and never cuts a blocked corner, so its reachable set is the 4-connected component of the start cell.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from tasks.occupancy import OccupancyGrid


@dataclass(frozen=True)
class FreeSpace:
    """The planner's grid with its free cells labelled by 4-connected component (0: blocked)."""

    grid: OccupancyGrid
    labels: np.ndarray

    @classmethod
    def of(cls, clearance: Callable[[np.ndarray], np.ndarray], base_clearance_m: float,
           bounds: tuple[float, float, float, float], cell_m: float) -> FreeSpace:
        """`clearance(xy (…, 2)) → m`: distance from cell centres to the nearest box footprint."""
        x0, x1, y0, y1 = bounds
        shape = (max(1, int(np.ceil((x1 - x0) / cell_m))), max(1, int(np.ceil((y1 - y0) / cell_m))))
        gx, gy = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
        centres = np.stack([x0 + (gx + 0.5) * cell_m, y0 + (gy + 0.5) * cell_m], axis=-1)
        blocked = clearance(centres) < base_clearance_m
        labels = np.zeros(shape, np.int32)
        ndimage.label(~blocked, output=labels)
        return cls(OccupancyGrid(np.array([x0, y0], float), cell_m, blocked), labels)

    def region(self, xy: np.ndarray) -> int:
        """The component of xy's cell; from a blocked cell (the robot close to a box), the nearest free cell's,
        as the planner leaves it."""
        cell = self.grid.cell(xy)
        if self.labels[cell]:
            return int(self.labels[cell])
        free = np.argwhere(self.labels > 0)
        if not len(free):
            return 0
        k = int(np.argmin(np.sum((free - np.array(cell)) ** 2, axis=1)))
        return int(self.labels[tuple(free[k])])

    def reachable(self, start_xy: np.ndarray, goal_xy: np.ndarray) -> bool:
        """Whether a path leads from start to goal (a goal in a blocked cell counts as reachable: the clearance
        rule judges it)."""
        goal = self.labels[self.grid.cell(goal_xy)]
        return not goal or goal == self.region(start_xy)

    def nearest_reachable(self, start_xy: np.ndarray, xy: np.ndarray) -> np.ndarray | None:
        """The centre of the cell nearest to xy that the start reaches (None when it reaches none)."""
        region = self.region(start_xy)
        cells = np.argwhere(self.labels == region) if region else np.zeros((0, 2), int)
        if not len(cells):
            return None
        centres = self.grid.origin + (cells + 0.5) * self.grid.cell_m
        return centres[int(np.argmin(np.linalg.norm(centres - np.asarray(xy, float)[:2], axis=1)))]
