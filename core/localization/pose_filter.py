"""The pose filter: T_world←odom and the covariance P of the base's world pose (x, y, yaw), an EKF.

Prediction (`odometry_prediction.py`) grows P; a registration gives a measured base pose z at its frame's
exposure. Only its constrained directions u_i (`degeneracy.py`, in (x, y, L·yaw)) are used:
    y = Uᵀ S ν,  ν = z ⊖ x̂,   Hm = Uᵀ S,   S_ν = Hm P Hmᵀ + R,   NIS = yᵀ S_ν⁻¹ y ≤ χ²(dof)
    K = P Hmᵀ S_ν⁻¹,  δ = K y,  P ← (I − K Hm) P (I − K Hm)ᵀ + K R Kᵀ
and the correction is the world-frame motion Δ = (x̂ ⊕ δ) ∘ x̂⁻¹, applied as T_world←odom ← Δ ∘ T_world←odom.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.angles import wrap_angle
from core.localization import se2
from core.localization.degeneracy import Directions
from core.localization.odometry_prediction import predict_covariance


@dataclass(frozen=True)
class Update:
    """One measurement's effect: `delta` the world-frame correction Δ (x, y, yaw), `nis`, `dof`, and the
    covariance P after it (applied only when the update is accepted)."""

    delta: np.ndarray
    nis: float
    dof: int
    P: np.ndarray


def measurement_information(dirs: Directions, sigma_xy_m: float, sigma_yaw_rad: float, inflate_below: float
                            ) -> tuple[np.ndarray, np.ndarray]:
    """The measurement model along the constrained directions: Hm = Uᵀ S (dof × 3, on x, y, yaw) and its noise R
    (a fixed std a direction, variance inflated by inflate_below / λ where the information λ is low); the pose's
    information from the measurement is Hmᵀ R⁻¹ Hm."""
    U = dirs.vectors[:, dirs.constrained]
    lever = dirs.scale[2, 2]
    base_var = (U[0] ** 2 + U[1] ** 2) * sigma_xy_m**2 + U[2] ** 2 * (lever * sigma_yaw_rad) ** 2
    inflation = np.maximum(1.0, inflate_below / dirs.values[dirs.constrained])
    return U.T @ dirs.scale, np.diag(base_var * inflation)


def position_std(P: np.ndarray, lever_m: float) -> float:
    """A position std (m) of the pose covariance P: the largest x-y std plus what the heading std sweeps at
    `lever_m` (m)."""
    return float(np.sqrt(np.max(np.linalg.eigvalsh(P[:2, :2]))) + lever_m * math.sqrt(max(float(P[2, 2]), 0.0)))


class PoseFilter:
    """T_world←odom (x, y, yaw) and P, the covariance of the base's world pose."""

    def __init__(self, sigma_m: float, sigma_rad: float) -> None:
        self.T_world_odom = np.zeros(3)
        self.P = np.diag([sigma_m**2, sigma_m**2, sigma_rad**2])

    def world_pose(self, odom_pose: np.ndarray) -> np.ndarray:
        return se2.compose(self.T_world_odom, odom_pose)

    def predict(self, odom_from: np.ndarray, odom_to: np.ndarray, drift_m: float, drift_rad: float) -> None:
        self.P = predict_covariance(self.P, odom_from, odom_to, float(self.T_world_odom[2]), drift_m, drift_rad)

    def update(self, predicted: np.ndarray, measured: np.ndarray, dirs: Directions, sigma_xy_m: float,
               sigma_yaw_rad: float, inflate_below: float) -> Update:
        """The update a measured base pose (world, at the frame's exposure) would make, along the constrained
        directions only; nothing is changed here (`apply` does)."""
        nu = np.array([measured[0] - predicted[0], measured[1] - predicted[1], wrap_angle(measured[2] - predicted[2])])
        if dirs.dof == 0:
            return Update(np.zeros(3), 0.0, 0, self.P)
        Hm, R = measurement_information(dirs, sigma_xy_m, sigma_yaw_rad, inflate_below)
        S = Hm @ self.P @ Hm.T + R
        y = Hm @ nu
        S_inv = np.linalg.inv(S)
        nis = float(y @ S_inv @ y)
        K = self.P @ Hm.T @ S_inv
        delta_state = K @ y
        I_KH = np.eye(3) - K @ Hm
        P = I_KH @ self.P @ I_KH.T + K @ R @ K.T
        corrected = np.array([predicted[0] + delta_state[0], predicted[1] + delta_state[1],
                              predicted[2] + delta_state[2]])
        delta = se2.compose(corrected, se2.inverse(predicted))
        return Update(delta, nis, dirs.dof, 0.5 * (P + P.T))

    def apply(self, delta: np.ndarray) -> None:
        """T_world←odom ← Δ ∘ T_world←odom."""
        self.T_world_odom = se2.compose(delta, self.T_world_odom)

    def sigma_xy_m(self, lever_m: float) -> float:
        """A position std for the correspondence radius (`position_std` of P)."""
        return position_std(self.P, lever_m)
