"""Base path planning: A* on the 2D occupancy through a subtask's waypoints, then smoothing.

A* is 8-connected with the octile heuristic. A start inside an inflated obstacle (the robot already
close to a box) searches outward to the nearest free cell first, so the planner never refuses to
leave. The path is shortcut by line of sight and resampled evenly.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from core.errors import StudioError
from tasks.occupancy import OccupancyGrid

_MOVES = [(-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0),
          (-1, -1, math.sqrt(2)), (-1, 1, math.sqrt(2)), (1, -1, math.sqrt(2)), (1, 1, math.sqrt(2))]


class NoPathError(StudioError, RuntimeError):
    """No collision-free base path exists on the current map."""


def _nearest_free(grid: OccupancyGrid, cell: tuple[int, int]) -> tuple[int, int]:
    free = np.argwhere(~grid.blocked)
    if len(free) == 0:
        raise NoPathError("the whole map is blocked")
    k = int(np.argmin(np.sum((free - np.array(cell)) ** 2, axis=1)))
    return int(free[k, 0]), int(free[k, 1])


def astar(grid: OccupancyGrid, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
    """Cells from start to goal (both free) on the 8-connected grid; raises `NoPathError`.

    The search runs on flat indices of the grid padded by a blocked border (no bounds checks) with the octile
    heuristic computed for all cells at once: numpy's scalar indexing and a Python call per expansion cost more
    than the search itself. Indices keep the (i, j) order, so the heap breaks ties as it would on cell tuples."""
    nx, ny = grid.blocked.shape
    width = ny + 2
    padded = np.ones((nx + 2, width), bool)
    padded[1:-1, 1:-1] = grid.blocked
    blocked = padded.ravel().tolist()
    di = np.abs(np.arange(-1, nx + 1) - goal[0])[:, None]
    dj = np.abs(np.arange(-1, ny + 1) - goal[1])[None, :]
    h = (np.maximum(di, dj) + (math.sqrt(2) - 1) * np.minimum(di, dj)).ravel().tolist()
    moves = [(dx * width + dy, step, dy, dx * width) for dx, dy, step in _MOVES]

    begin, end = (start[0] + 1) * width + start[1] + 1, (goal[0] + 1) * width + goal[1] + 1
    g = [math.inf] * len(blocked)
    g[begin] = 0.0
    parent = [-1] * len(blocked)
    closed = bytearray(len(blocked))
    frontier = [(h[begin], 0.0, begin)]
    while frontier:
        _, cost, cur = heapq.heappop(frontier)
        if cur == end:
            path = [cur]
            while parent[cur] >= 0:
                cur = parent[cur]
                path.append(cur)
            return [(c // width - 1, c % width - 1) for c in reversed(path)]
        if closed[cur]:
            continue
        closed[cur] = 1
        for offset, step, side_j, side_i in moves:
            nxt = cur + offset
            if blocked[nxt]:
                continue
            if side_j and side_i and (blocked[cur + side_i] or blocked[cur + side_j]):
                continue  # no corner cutting: both cells beside the diagonal must be free
            new = cost + step
            if new < g[nxt]:
                g[nxt] = new
                parent[nxt] = cur
                heapq.heappush(frontier, (new + h[nxt], new, nxt))
    raise NoPathError("no path to the goal on the current map")


def shortcut(grid: OccupancyGrid, points: np.ndarray) -> np.ndarray:
    """Greedy line-of-sight shortcutting of a polyline: from each kept point, the farthest point in free sight."""
    out = [points[0]]
    i = 0
    while i < len(points) - 1:
        free = grid.segments_free(points[i], points[i + 2:]) if i + 2 < len(points) else np.zeros(0, bool)
        j = i + 2 + int(np.flatnonzero(free)[-1]) if free.any() else i + 1
        out.append(points[j])
        i = j
    return np.array(out)


def resample(points: np.ndarray, spacing_m: float) -> np.ndarray:
    """Evenly spaced points along a polyline (first and last kept)."""
    if len(points) < 2:
        return np.asarray(points, float).reshape(-1, 2)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] < 1e-9:
        return points[:1]
    samples = np.linspace(0.0, s[-1], max(2, int(np.ceil(s[-1] / spacing_m)) + 1))
    return np.stack([np.interp(samples, s, points[:, 0]), np.interp(samples, s, points[:, 1])], axis=1)


def _reachable_goal(grid: OccupancyGrid, goal: np.ndarray, last: bool, snap_m: float,
                    notes: list[str]) -> np.ndarray | None:
    """The goal itself if free; else an intermediate waypoint is skipped (None) and the final goal moves to
    the nearest free cell within `snap_m`; farther than that it raises."""
    if not grid.blocked[grid.cell(goal)]:
        return goal
    where = f"({goal[0]:.2f}, {goal[1]:.2f})"
    if not last:
        notes.append(f"waypoint {where} is too close to an obstacle: skipped")
        return None
    free = grid.centre(_nearest_free(grid, grid.cell(goal)))
    if np.linalg.norm(free - goal) > snap_m:
        raise NoPathError(f"no path to the goal {where}: it is too close to an obstacle for the base")
    notes.append(f"goal {where} is too close to an obstacle: going to ({free[0]:.2f}, {free[1]:.2f})")
    return free


def plan_path(grid: OccupancyGrid, start_xy: np.ndarray, goals_xy: list[np.ndarray], spacing_m: float = 0.1,
              snap_m: float = 0.5, notes: list[str] | None = None, first_waypoint: int = 1) -> np.ndarray:
    """Smoothed path (P×2) from start through each goal in order (blocked goals: see `_reachable_goal`;
    what was changed is appended to `notes`). Messages number the goals from `first_waypoint` (the
    subtask's own number of the first one, when earlier waypoints were passed)."""
    notes = notes if notes is not None else []
    pieces = [np.asarray(start_xy, float)[None]]
    here = np.asarray(start_xy, float)
    for i, goal in enumerate(goals_xy):
        goal = _reachable_goal(grid, np.asarray(goal, float), i == len(goals_xy) - 1, snap_m, notes)
        if goal is None:
            continue
        g_cell = grid.cell(goal)
        s_cell = grid.cell(here)
        if grid.blocked[s_cell]:
            s_cell = _nearest_free(grid, s_cell)
        try:
            cells = astar(grid, s_cell, g_cell)
        except NoPathError:
            what = "the goal" if i == len(goals_xy) - 1 else f"waypoint {first_waypoint + i}"
            raise NoPathError(f"no path to {what} ({goal[0]:.2f}, {goal[1]:.2f}) on the current map") from None
        start = here if grid.is_free(here) else grid.centre(cells[0])
        # the ends are the start and the goal themselves, also when both lie in one cell
        middle = grid.origin + (np.array(cells[1:-1], float).reshape(-1, 2) + 0.5) * grid.cell_m
        pts = np.vstack([start, middle, goal])
        pieces.append(shortcut(grid, pts)[1:])
        here = goal
    return resample(np.concatenate(pieces), spacing_m)
