"""SO(3) helpers for the EE orientation error of eq. (5): Log(R^T R_d) and its Jacobian."""

from __future__ import annotations

import numpy as np

_SMALL = 1e-6


def skew(w: np.ndarray) -> np.ndarray:
    """[w]× for w (..., 3) → (..., 3, 3)."""
    w = np.asarray(w, float)
    z = np.zeros(w.shape[:-1])
    return np.stack([np.stack([z, -w[..., 2], w[..., 1]], -1),
                     np.stack([w[..., 2], z, -w[..., 0]], -1),
                     np.stack([-w[..., 1], w[..., 0], z], -1)], -2)


def log3(R: np.ndarray) -> np.ndarray:
    """Exact rotation vector of R (..., 3, 3) → (..., 3), angle in [0, π]; stable near 0 and π."""
    R = np.asarray(R, float)
    w = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    s = np.linalg.norm(w, axis=-1)
    c = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arctan2(s, c)
    scale = np.where(s > _SMALL, theta / np.maximum(s, _SMALL), 1.0 + s**2 / 6.0)
    out = w * scale[..., None]
    near_pi = (c < -0.99) & (s < 0.1)
    if np.any(near_pi):
        out = np.where(near_pi[..., None], _log3_near_pi(R, theta), out)
    return out


def _log3_near_pi(R: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Near θ = π the antisymmetric part vanishes: read the axis from the symmetric part."""
    B = (R + np.swapaxes(R, -1, -2)) / 2.0 - np.cos(theta)[..., None, None] * np.eye(3)
    diag = np.clip(np.diagonal(B, axis1=-2, axis2=-1) / np.maximum(1.0 - np.cos(theta), 1e-12)[..., None], 0.0, None)
    axis = np.sqrt(diag)
    k = np.argmax(axis, axis=-1)
    # fix signs relative to the largest component using the off-diagonal terms
    col = np.take_along_axis(B, k[..., None, None].repeat(3, -1), axis=-2)[..., 0, :]
    axis = col / np.maximum(np.linalg.norm(col, axis=-1, keepdims=True), 1e-12)
    w = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    sign = np.where(np.sum(axis * w, axis=-1) < 0.0, -1.0, 1.0)
    return axis * (sign * theta)[..., None]


def exp3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (..., 3) by Rodrigues' formula."""
    w = np.asarray(w, float)
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = skew(w)
    a = np.where(th > _SMALL, np.sin(th) / np.maximum(th, _SMALL), 1.0 - th**2 / 6.0)
    b = np.where(th > _SMALL, (1.0 - np.cos(th)) / np.maximum(th, _SMALL) ** 2, 0.5 - th**2 / 24.0)
    return np.eye(3) + a * K + b * (K @ K)


def left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """J_l^{-1}(φ): Log(exp(δ) exp(φ)) ≈ φ + J_l^{-1}(φ) δ for small δ. φ (..., 3) → (..., 3, 3)."""
    phi = np.asarray(phi, float)
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    safe = np.maximum(th, _SMALL)
    sin = np.sin(np.minimum(safe, np.pi - 1e-9))
    coef = np.where(th > 1e-4, 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * sin), 1.0 / 12.0 + th**2 / 720.0)
    return np.eye(3) - 0.5 * K + coef * (K @ K)
