"""The robot's estimate of its base pose: dead reckoning whose error is a random walk (the sensor model).

Each update takes the true motion since the last one in the base frame (dx, dy, dyaw) and integrates
it corrupted by noise whose variance grows with the motion: std `drift_m` · √|d| per axis for the
d metres driven, `drift_rad` · √|dyaw| for the radians turned. So the position error after s metres
has a std of drift_m · √s per axis (plus the lateral error that a heading error sweeps out), the
heading error after θ radians drift_rad · √θ: a localisation whose error grows with the distance
driven, as wheel odometry's does, independent of how often it is updated (Brownian increments).

The estimate and the truth differ by a rigid motion of the plane E (est = E ∘ true): `to_estimate`
maps true world poses and vectors into the world the robot believes in, `to_true` maps its commands
back. A teleport (`SimWorld.set_robot`) restarts the estimate at the true pose. A slip (`slip`,
`SensorParams.slip_at_s`) is a one-off error the estimate silently keeps.
"""

from __future__ import annotations

import math

import numpy as np

from core.angles import wrap_angle


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


class DriftingOdometry:
    """Base pose estimate (x, y, yaw) with random-walk error per metre driven and per radian turned."""

    def __init__(self, drift_m: float, drift_rad: float, rng: np.random.Generator) -> None:
        self.drift_m = drift_m
        self.drift_rad = drift_rad
        self._rng = rng
        self._true: np.ndarray | None = None
        self._est = np.zeros(3)
        self.distance_m = 0.0
        """True distance driven since the last reset (m)."""
        self.turned_rad = 0.0
        """True angle turned since the last reset (rad)."""

    def reset(self, true_pose: np.ndarray) -> None:
        """Estimate = truth (start, teleport)."""
        self._true = np.array(true_pose, dtype=float)
        self._est = self._true.copy()
        self.distance_m = self.turned_rad = 0.0

    def update(self, true_pose: np.ndarray) -> None:
        """Integrate the true motion since the last update, with its noise."""
        true_pose = np.asarray(true_pose, dtype=float)
        if self._true is None:
            self.reset(true_pose)
            return
        d_body = _rot(self._true[2]).T @ (true_pose[:2] - self._true[:2])
        d_yaw = wrap_angle(true_pose[2] - self._true[2])
        dist, turn = float(np.hypot(*d_body)), abs(d_yaw)
        if dist > 0.0 or turn > 0.0:
            d_body = d_body + self._rng.standard_normal(2) * self.drift_m * math.sqrt(dist)
            d_yaw = d_yaw + self._rng.standard_normal() * self.drift_rad * math.sqrt(turn)
            self._est[:2] += _rot(self._est[2]) @ d_body
            self._est[2] = self._est[2] + d_yaw
            self.distance_m += dist
            self.turned_rad += turn
        self._true = true_pose.copy()

    def slip(self, d_body_m: tuple[float, float], d_yaw_rad: float) -> None:
        """A one-off error (a wheel slip, a kidnap): the estimate jumps by d_body_m (x, y in the base frame as
        the robot believes it, m) and d_yaw_rad about the base's centre, while the truth stays where it is. The
        error is then carried on like drift (est = E ∘ true with the new E); only a reset clears it."""
        self._est[:2] += _rot(self._est[2]) @ np.asarray(d_body_m, dtype=float)
        self._est[2] = self._est[2] + d_yaw_rad

    @property
    def estimate(self) -> np.ndarray:
        """The believed base pose (x, y, yaw) at the last update."""
        return self._est.copy()

    @property
    def error(self) -> np.ndarray:
        """Estimate minus truth at the last update (x, y in m, yaw wrapped, rad)."""
        if self._true is None:
            return np.zeros(3)
        e = self._est - self._true
        e[2] = wrap_angle(e[2])
        return e

    def to_estimate(self, vector_xy: np.ndarray) -> np.ndarray:
        """A world-frame planar vector (a velocity) of the true world in the believed world."""
        return _rot(self.error[2]) @ np.asarray(vector_xy, dtype=float)

    def to_true(self, vector_xy: np.ndarray) -> np.ndarray:
        """A planar vector of the believed world (a commanded velocity) in the true world."""
        return _rot(-self.error[2]) @ np.asarray(vector_xy, dtype=float)
