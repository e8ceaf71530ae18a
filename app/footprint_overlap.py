"""Whether two boxes' footprints overlap: the rectangles (centre, yaw, extent along their own x and y) seen from
above, tested on the four separating axes (their edge normals)."""

from __future__ import annotations

import math

import numpy as np


def _half_width(yaw: float, extent: np.ndarray, axis_yaw: float) -> float:
    """Half the width of a rectangle (`yaw`, `extent` x, y) projected on the axis at `axis_yaw`."""
    d = yaw - axis_yaw
    return (float(extent[0]) * abs(math.cos(d)) + float(extent[1]) * abs(math.sin(d))) / 2.0


def overlap_depth(a_centre: np.ndarray, a_yaw: float, a_extent: np.ndarray,
                  b_centre: np.ndarray, b_yaw: float, b_extent: np.ndarray) -> float:
    """How far the two footprints overlap (m) along the separating axis where they overlap least; ≤ 0 when they
    are apart or touch. Positions in the world (x, y used), yaws in rad, extents full (m)."""
    offset = np.asarray(b_centre, float)[:2] - np.asarray(a_centre, float)[:2]
    depth = math.inf
    for axis_yaw in (a_yaw, a_yaw + math.pi / 2, b_yaw, b_yaw + math.pi / 2):
        axis = np.array([math.cos(axis_yaw), math.sin(axis_yaw)])
        gap = abs(float(axis @ offset))
        reach = _half_width(a_yaw, np.asarray(a_extent, float), axis_yaw) + _half_width(
            b_yaw, np.asarray(b_extent, float), axis_yaw)
        depth = min(depth, reach - gap)
    return depth
