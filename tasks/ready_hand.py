"""The arm's ready pose, turned at the shoulder: what the arm holds while the base drives.

Held as joints (`READY_Q`'s arm with the pan moved by a bearing), not as a hand pose: a hand pose is reached by up to
eight arm configurations, and the Gauss-Newton steps of the controller switched between them near singularities
(the elbow stretched after a pick, the wrist at a corner), after which the arm drove the rest of a run in another
configuration, its joints wound toward their limits. In joint space the ready pose is one configuration. The pan
faces the hand camera toward the path ahead and wrist 1 tilts it down onto that point: the ready pose's own camera
looks 23° down, over the floor where a vacated place 0.6 m high would be seen through (its rays reach the floor
beyond the cameras' range, which is no evidence).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.robot.model import READY_Q, RobotModel

WRIST_1 = 3
"""Index of wrist 1 among the arm's joints: its axis is parallel to the lift's and the elbow's, so with the ready
wrist 2 it tilts the hand camera up or down without moving the hand much."""


@dataclass(frozen=True)
class ReadyHand:
    """In the base frame: the ready hand's position (3,) (m), the heading and pitch of its camera axis (rad), the
    shoulder pan axis's x, y (2,) (m), the point the arm turns about, and the camera's pitch per radian of wrist 1."""

    position: np.ndarray
    heading_rad: float
    pan_axis_xy: np.ndarray
    pitch_rad: float = 0.0
    pitch_per_wrist_1: float = -1.0

    @classmethod
    def of(cls, robot: RobotModel) -> ReadyHand:
        """The ready pose of `robot` (its base at the origin)."""
        q = np.concatenate([[0.0, 0.0, 0.0], READY_Q[3:]])
        poses = robot.frame_poses(q, ("ee", "shoulder_link"))
        T = poses["ee"]
        tilted = q.copy()
        tilted[3 + WRIST_1] += 0.1
        gain = (_pitch(robot.frame_poses(tilted, ("ee",))["ee"]) - _pitch(T)) / 0.1
        return cls(T[:3, 3].copy(), float(np.arctan2(T[1, 0], T[0, 0])), poses["shoulder_link"][:2, 3].copy(),
                   _pitch(T), gain)

    def joints(self, bearing_rad: np.ndarray, pitch_rad: np.ndarray | None = None) -> np.ndarray:
        """Arm joints (K, 6): the ready pose with the shoulder pan turned by each bearing (rad) and, with `pitch_rad`,
        wrist 1 tilted so the camera axis points that far below (negative) or above the horizontal."""
        bearing = np.atleast_1d(np.asarray(bearing_rad, float))
        q = np.tile(READY_Q[3:], (len(bearing), 1))
        q[:, 0] += bearing
        if pitch_rad is not None:
            q[:, WRIST_1] += (np.asarray(pitch_rad, float) - self.pitch_rad) / self.pitch_per_wrist_1
        return q

    def bearing_to(self, points_b: np.ndarray) -> np.ndarray:
        """Bearing (rad) of base-frame points (K, 2) from the pan axis, against the ready camera's heading: the pan
        turn that faces the hand camera toward them (0 for a point straight ahead)."""
        d = np.asarray(points_b, float)[:, :2] - self.pan_axis_xy
        return (np.arctan2(d[:, 1], d[:, 0]) - self.heading_rad + np.pi) % (2 * np.pi) - np.pi

    def pitch_to(self, points_b: np.ndarray, height_m: float) -> np.ndarray:
        """Pitch (rad, negative down) from the hand to base-frame points (K, 2) at `height_m` once the pan faces
        them: their distance from the pan axis less the hand's reach from it, against the height below the hand."""
        reach = float(np.hypot(*(self.position[:2] - self.pan_axis_xy)))
        ahead = np.hypot(*(np.asarray(points_b, float)[:, :2] - self.pan_axis_xy).T) - reach
        return np.arctan2(height_m - self.position[2], np.maximum(ahead, 0.1))


def _pitch(T: np.ndarray) -> float:
    """Elevation (rad) of a frame's x axis (the hand camera's optical axis) above the horizontal."""
    x = T[:3, 0]
    return float(np.arctan2(x[2], np.hypot(x[0], x[1])))
