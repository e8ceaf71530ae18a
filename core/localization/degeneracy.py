"""Degeneracy: which directions of (x, y, yaw) a registration constrains, from its Hessian H.

small_gicp's H (6×6, order rx, ry, rz, tx, ty, tz) is the information of a right perturbation of the camera
pose, T·exp(δ). It is moved to world twists (δ_l = Ad(T⁻¹) δ_w), re-parametrised by the base's own motion
(dx, dy, dψ about the base, and the nuisance rx, ry, dz), and the nuisance is Schur-complemented out:
    H₃ = H_aa − H_ab H_bb⁻¹ H_ba
Yaw is weighed as a displacement at `yaw_lever_m`, H₃ is divided by the inlier count, and its
eigen-directions with information below `degenerate_information` get no correction: the floor alone fixes
z, roll and pitch and reads ~0.6 along itself. H⁻¹ is never taken as the covariance as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Directions:
    """Eigen-directions of the per-inlier information on (x, y, L·yaw): `vectors` columns, `values` per
    direction, `constrained` mask; `scale` = diag(1, 1, L) maps (x, y, yaw) into those coordinates."""

    values: np.ndarray
    vectors: np.ndarray
    constrained: np.ndarray
    scale: np.ndarray

    @property
    def dof(self) -> int:
        return int(np.sum(self.constrained))

    @property
    def degenerate(self) -> bool:
        """Some direction is unconstrained."""
        return self.dof < 3


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def world_information(H_local: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
    """H on world twists (ω, v) from H on the camera's right perturbation (both ordered rotation first)."""
    R, t = T_world_camera[:3, :3], T_world_camera[:3, 3]
    Rt = R.T
    A = np.zeros((6, 6))
    A[:3, :3] = Rt
    A[3:, 3:] = Rt
    A[3:, :3] = _skew(-Rt @ t) @ Rt
    return A.T @ H_local @ A


def planar_information(H_world: np.ndarray, base_xy: np.ndarray) -> np.ndarray:
    """H₃ on the base's (dx, dy, dψ), the rest (rx, ry, dz) Schur-complemented out."""
    px, py = float(base_xy[0]), float(base_xy[1])
    B = np.zeros((6, 6))  # columns: dx, dy, dpsi, rx, ry, dz → world twist (wx, wy, wz, vx, vy, vz)
    B[3, 0] = 1.0
    B[4, 1] = 1.0
    B[2, 2], B[3, 2], B[4, 2] = 1.0, py, -px
    B[0, 3] = 1.0
    B[1, 4] = 1.0
    B[5, 5] = 1.0
    Hp = B.T @ H_world @ B
    Haa, Hab, Hbb = Hp[:3, :3], Hp[:3, 3:], Hp[3:, 3:]
    return Haa - Hab @ np.linalg.pinv(Hbb) @ Hab.T


def directions(H_local: np.ndarray, T_world_camera: np.ndarray, base_xy: np.ndarray, inliers: int,
               yaw_lever_m: float, threshold: float) -> Directions:
    """The constrained and unconstrained directions of one registration."""
    H3 = planar_information(world_information(H_local, T_world_camera), base_xy)
    scale = np.diag([1.0, 1.0, yaw_lever_m])
    inv_scale = np.linalg.inv(scale)
    Hs = inv_scale @ H3 @ inv_scale / max(inliers, 1)
    values, vectors = np.linalg.eigh(0.5 * (Hs + Hs.T))
    return Directions(values, vectors, values >= threshold, scale)


def rms_lever(points_camera: np.ndarray, T_world_camera: np.ndarray, base_xy: np.ndarray) -> float:
    """RMS horizontal distance (m, at least 0.1) of the registered points (camera frame, placed by T_world_camera)
    from the base: a yaw dψ moves them about this far per radian, so yaw in units of lever·dψ compares with x and y
    (the floor gives ~0.5 per inlier along every such direction)."""
    T = T_world_camera
    xy = (points_camera @ T[:3, :3].T + T[:3, 3])[:, :2] - base_xy
    return max(float(np.sqrt(np.mean(np.sum(xy**2, axis=1)))), 0.1)
