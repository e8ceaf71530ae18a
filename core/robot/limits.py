"""Position, velocity and acceleration limits of the 9 joints (docs/method.md, "Settings")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class JointLimits:
    """Box limits q_min ≤ q ≤ q_max, |v| ≤ v_max, |u| ≤ a_max (arrays of 9, SI units)."""

    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray

    def clip_velocity(self, v: np.ndarray) -> np.ndarray:
        """Velocity clipped into ±v_max; NaN becomes 0 (a safe stop, never an unknown motion)."""
        v = np.where(np.isfinite(v), v, 0.0)
        return np.clip(v, -self.v_max, self.v_max)

    def within(self, q: np.ndarray, v: np.ndarray | None = None, tol: float = 1e-9) -> bool:
        """True when q (and v) respect the limits."""
        ok = bool(np.all(q >= self.q_min - tol) and np.all(q <= self.q_max + tol))
        if v is not None:
            ok = ok and bool(np.all(np.abs(v) <= self.v_max + tol))
        return ok
