"""Planar rigid motions (x, y, yaw) as 3-vectors: composition, inverse, and the lift to 4×4 transforms."""

from __future__ import annotations

import math

import numpy as np

from core.angles import wrap_angle


def rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a ∘ b: b expressed in a's frame, then a."""
    xy = np.asarray(a[:2], float) + rot(float(a[2])) @ np.asarray(b[:2], float)
    return np.array([xy[0], xy[1], wrap_angle(float(a[2]) + float(b[2]))])


def inverse(a: np.ndarray) -> np.ndarray:
    xy = -(rot(float(a[2])).T @ np.asarray(a[:2], float))
    return np.array([xy[0], xy[1], wrap_angle(-float(a[2]))])


def to_matrix(a: np.ndarray) -> np.ndarray:
    """The planar motion as a 4×4 transform (rotation about z)."""
    T = np.eye(4)
    T[:2, :2] = rot(float(a[2]))
    T[:2, 3] = a[:2]
    return T


def from_matrix(T: np.ndarray) -> np.ndarray:
    """The planar part (x, y, yaw about z) of a 4×4 transform."""
    return np.array([T[0, 3], T[1, 3], math.atan2(T[1, 0], T[0, 0])])
