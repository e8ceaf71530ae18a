"""Prediction: the world pose's covariance P grows with each odometry increment (σ ∝ √distance, √angle).

The odometry's error is a random walk per metre driven and per radian turned (as the sensor model's is,
`core/sim/odometry_drift.py`); a heading error sweeps a lateral error along the distance driven after it.
With the world-frame displacement d of the increment:
    F = [[1, 0, -d_y], [0, 1, d_x], [0, 0, 1]],   Q = diag(σ_m² s, σ_m² s, σ_r² |Δψ|)
    P ← F P Fᵀ + Q
The mean needs no prediction: T_world←odom stays as it is between corrections.
"""

from __future__ import annotations

import numpy as np

from core.angles import wrap_angle
from core.localization.se2 import rot


def predict_covariance(P: np.ndarray, odom_from: np.ndarray, odom_to: np.ndarray, world_yaw_offset: float,
                       drift_m: float, drift_rad: float) -> np.ndarray:
    """P (3×3, world x, y, yaw) after the odometry moved from `odom_from` to `odom_to` (x, y, yaw in the
    odometry frame); `world_yaw_offset` is T_world←odom's yaw (turns the displacement into the world)."""
    d = rot(world_yaw_offset) @ (np.asarray(odom_to[:2], float) - np.asarray(odom_from[:2], float))
    distance = float(np.hypot(*d))
    turn = abs(wrap_angle(float(odom_to[2]) - float(odom_from[2])))
    F = np.array([[1.0, 0.0, -d[1]], [0.0, 1.0, d[0]], [0.0, 0.0, 1.0]])
    Q = np.diag([drift_m**2 * distance, drift_m**2 * distance, drift_rad**2 * turn])
    return F @ P @ F.T + Q
