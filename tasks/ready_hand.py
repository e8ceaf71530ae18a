"""The arm's ready pose, turned at the shoulder: what the arm holds while the base drives.

Held as joints (`READY_Q`'s arm with the pan moved by a bearing), not as a hand pose: a hand pose is reached by up to
eight arm configurations, and the Gauss-Newton steps of the controller switched between them near singularities
(the elbow stretched after a pick, the wrist at a corner), after which the arm drove the rest of a run in another
configuration, its joints wound toward their limits. In joint space the ready pose is one configuration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.angles import wrap_angle
from core.robot.model import READY_Q, RobotModel


@dataclass(frozen=True)
class ReadyHand:
    """In the base frame: the ready hand's position (3,) (m), the heading of its camera axis (rad) and the shoulder
    pan axis's x, y (2,) (m), the point the arm turns about."""

    position: np.ndarray
    heading_rad: float
    pan_axis_xy: np.ndarray

    @classmethod
    def of(cls, robot: RobotModel) -> ReadyHand:
        """The ready pose of `robot` (its base at the origin)."""
        poses = robot.frame_poses(np.concatenate([[0.0, 0.0, 0.0], READY_Q[3:]]), ("ee", "shoulder_link"))
        T = poses["ee"]
        return cls(T[:3, 3].copy(), float(np.arctan2(T[1, 0], T[0, 0])), poses["shoulder_link"][:2, 3].copy())

    @staticmethod
    def joints(bearing_rad: np.ndarray) -> np.ndarray:
        """Arm joints (K, 6): the ready pose with the shoulder pan turned by each bearing (rad)."""
        bearing = np.atleast_1d(np.asarray(bearing_rad, float))
        q = np.tile(READY_Q[3:], (len(bearing), 1))
        q[:, 0] += bearing
        return q

    def bearing_to(self, points_b: np.ndarray) -> np.ndarray:
        """Bearing (rad) of base-frame points (K, 2) from the pan axis, against the ready camera's heading: the pan
        turn that faces the hand camera toward them (0 for a point straight ahead)."""
        d = np.asarray(points_b, float)[:, :2] - self.pan_axis_xy
        return wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - self.heading_rad)
