"""Whether the base fits at a goal: its footprint at the goal's heading keeps a clearance from the map's points.

A* plans on obstacles grown by a circle (`SequencerParams.inflation_m`, `inflation_min_m`), so a blocked final goal
is moved to a cell whose centre keeps that radius. The controller keeps delta_safe from the base's boxes at their
heading instead (`core/htmpc/box_barrier.py`): facing a box with another behind it, a cell 0.65 m from that one
leaves the base's back (0.48 m from its centre) 0.17 m from it, and the base is held short of such a goal until
its timeout. A goal is only moved to where the footprint fits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BaseFit:
    """The base's footprint (`half_m`: half length, half width) at heading `yaw`, `clearance_m` from `points_xy`."""

    points_xy: np.ndarray
    yaw: float
    half_m: tuple[float, float]
    clearance_m: float

    @classmethod
    def near(cls, points: np.ndarray, goal_xy: np.ndarray, reach_m: float, yaw: float, half_m: tuple[float, float],
             clearance_m: float, z_range_m: tuple[float, float]) -> BaseFit:
        """Only the points between the heights in `z_range_m` within `reach_m` of the goal (plus the footprint's
        radius and the clearance) can matter."""
        pts = np.asarray(points, float).reshape(-1, 3)
        pts = pts[(pts[:, 2] >= z_range_m[0]) & (pts[:, 2] <= z_range_m[1]), :2]
        radius = reach_m + math.hypot(*half_m) + clearance_m
        pts = pts[np.sum((pts - np.asarray(goal_xy, float)[:2]) ** 2, axis=1) <= radius**2]
        return cls(pts, yaw, half_m, clearance_m)

    def distance(self, xy: np.ndarray) -> float:
        """Least distance (m) from the footprint at xy to the points (negative: a point inside; inf: none)."""
        if len(self.points_xy) == 0:
            return math.inf
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        d = self.points_xy - np.asarray(xy, float)[:2]
        local = np.abs(np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]]))
        q = local - np.asarray(self.half_m, float)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return float(np.min(outside + np.minimum(q.max(axis=1), 0.0)))

    def __call__(self, xy: np.ndarray) -> bool:
        """Does the base fit at xy?"""
        return self.distance(xy) >= self.clearance_m
