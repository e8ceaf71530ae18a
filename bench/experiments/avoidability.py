"""Could any controller have avoided a box pushed in front of the base? A physical bound for E3.

The base (its footprint rectangle, in its own frame, driving along +x at speed v) keeps its velocity for
the closed-loop delay, then applies one of the extreme manoeuvres its limits allow, each axis of the
omnidirectional base at ±a_max up to ±v_max: brake; brake and sidestep left or right; sidestep left or
right at full speed. The push was avoidable if one of them never overlaps the box (2D, the box's
footprint: every pushed box stands on the floor and is taller than the base). This ignores the control
period and the actuators' lag (a bound, not a prediction), and yaw (turning does not help a rectangle
dodge faster than translating it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MANOEUVRES = {"brake": (1.0, 0.0), "brake_left": (1.0, 1.0), "brake_right": (1.0, -1.0),
              "left": (0.0, 1.0), "right": (0.0, -1.0)}
"""(braking on x, sidestep direction on y) of each manoeuvre."""


@dataclass(frozen=True)
class Push:
    """A box relative to the base at the moment it appears: centre (x ahead, y left), yaw, footprint size."""

    x_m: float
    y_m: float
    yaw: float
    size_m: tuple[float, float]


def _corners(cx: float, cy: float, yaw: float, half: tuple[float, float]) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    local = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * np.asarray(half)
    return local @ np.array([[c, s], [-s, c]]) + [cx, cy]


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex quadrilaterals (4×2 corners each)."""
    for poly in (a, b):
        for i in range(4):
            edge = poly[(i + 1) % 4] - poly[i]
            axis = np.array([-edge[1], edge[0]])
            pa, pb = a @ axis, b @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def manoeuvre_clear(push: Push, half_base: tuple[float, float], speed: float, delay_s: float, a_max: float,
                    v_max: float, braking: float, side: float, horizon_s: float = 4.0, dt: float = 0.005) -> bool:
    """True if the base never overlaps the box under one manoeuvre (see MANOEUVRES)."""
    box = _corners(push.x_m, push.y_m, push.yaw, (push.size_m[0] / 2, push.size_m[1] / 2))
    x = y = vy = 0.0
    vx = speed
    for k in range(int(horizon_s / dt)):
        if k * dt >= delay_s:
            vx = max(0.0, vx - braking * a_max * dt)
            vy = float(np.clip(vy + side * a_max * dt, -v_max, v_max))
        x += vx * dt
        y += vy * dt
        if _overlap(_corners(x, y, 0.0, half_base), box):
            return False
        if vx == 0.0 and (side == 0.0 or x + half_base[0] < push.x_m - 2.0):
            return True
    return True


def avoidable_by(push: Push, half_base: tuple[float, float], speed: float, delay_s: float, a_max: float,
                 v_max: float) -> list[str]:
    """The manoeuvres of MANOEUVRES that avoid the box."""
    return [name for name, (braking, side) in MANOEUVRES.items()
            if manoeuvre_clear(push, half_base, speed, delay_s, a_max, v_max, braking, side)]
