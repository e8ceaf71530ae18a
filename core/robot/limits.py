"""Position, velocity and acceleration limits of the 9 joints (docs/method.md, "Settings")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class JointLimits:
    """Box limits q_min ≤ q ≤ q_max, |v| ≤ v_max, |u| ≤ a_max (arrays of 9, SI units), and the base's planar
    speed ‖(vx, vy)‖ ≤ `planar_speed`."""

    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray

    @property
    def planar_speed(self) -> float:
        """The base's speed limit over the floor (m/s): the norm of (vx, vy), whichever way it drives (the
        per-axis limits alone let it drive √2 × as fast along a diagonal)."""
        return float(min(self.v_max[0], self.v_max[1]))

    def clip_velocity(self, v: np.ndarray) -> np.ndarray:
        """Velocity (9, or …×9) with the base's (vx, vy) scaled back to `planar_speed` where its norm is over it
        (the direction kept), then clipped into ±v_max; NaN becomes 0 (a safe stop, never an unknown motion)."""
        v = np.array(np.where(np.isfinite(v), v, 0.0), dtype=float)
        speed = np.hypot(v[..., 0], v[..., 1])
        scale = np.minimum(1.0, self.planar_speed / np.maximum(speed, 1e-12))
        v[..., 0] *= scale
        v[..., 1] *= scale
        return np.clip(v, -self.v_max, self.v_max)

    def within(self, q: np.ndarray, v: np.ndarray | None = None, tol: float = 1e-9) -> bool:
        """True when q (and v) respect the limits."""
        ok = bool(np.all(q >= self.q_min - tol) and np.all(q <= self.q_max + tol))
        if v is not None:
            ok = ok and bool(np.all(np.abs(v) <= self.v_max + tol))
            ok = ok and bool(np.all(np.hypot(v[..., 0], v[..., 1]) <= self.planar_speed + tol))
        return ok
