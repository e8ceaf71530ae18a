"""Robot self-filter: drop the points the cameras see of the robot's own body.

The body is the union of the collision spheres (centre P_j(q), radius r_j) of `RobotModel`, grown
by a margin, and of the base's box (`RobotParams.base_size_m`, from the floor up, in the base frame
x, y, yaw = q[:3]). The spheres are conservative where they reach (anything inside them is the robot
or a collision the controller must already prevent), but the 0.55 m base sphere leaves the corners
and top edges of the 0.96 × 0.79 m base out: seen by the hand camera looking down, they became
objects at the robot's own base in 10 of 60 random configurations. Nor do the spheres cover the arm's
mount and shoulder (`LINK_SPHERES` does, for the filter only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.robot.model import RobotModel

LINK_SPHERES: tuple[tuple[str, float], ...] = (("base_link", 0.15), ("shoulder_link", 0.15))
"""Spheres (frame origin, radius m) for the parts of the arm the collision spheres leave out: without them
the hand camera mapped the UR10's shoulder as an object in 2 of 200 random configurations."""


class SelfFilter:
    """Masks points outside the robot's collision spheres at configuration q."""

    def __init__(self, robot: RobotModel, margin_m: float = 0.0, base_margin_m: float = 0.03) -> None:
        self.robot = robot
        self.radii = np.concatenate([robot.sphere_radii, [r for _, r in LINK_SPHERES]]) + margin_m
        lx, ly, lz = robot.params.base_size_m
        self.base_half = np.array([lx / 2, ly / 2]) + base_margin_m
        self.base_top = lz + base_margin_m

    def spheres(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (M×3) and grown radii (M,) at q: the collision spheres and `LINK_SPHERES`."""
        poses = self.robot.frame_poses(q, tuple(name for name, _ in LINK_SPHERES))
        links = np.array([poses[name][:3, 3] for name, _ in LINK_SPHERES])
        return np.concatenate([self.robot.sphere_centres(q), links]), self.radii

    def body(self, q: np.ndarray) -> RobotBody:
        """The robot's body at q: its spheres and its base box."""
        centres, radii = self.spheres(q)
        return RobotBody(centres, radii, np.asarray(q[:3], dtype=float), self.base_half, self.base_top)

    def outside(self, points: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Mask of the points (N×3) that lie outside the robot's body at q."""
        return self.body(q).outside(points)


@dataclass(frozen=True)
class RobotBody:
    """Collision spheres (centres M×3, radii M) and the base box (pose x, y, yaw; half sides; top height)."""

    centres: np.ndarray
    radii: np.ndarray
    base_pose: np.ndarray
    base_half: np.ndarray
    base_top: float

    def outside(self, points: np.ndarray) -> np.ndarray:
        """Mask of the points (N×3) outside every sphere and outside the base box."""
        keep = outside_spheres(points, self.centres, self.radii)
        x, y, yaw = self.base_pose
        c, s = np.cos(yaw), np.sin(yaw)
        dx, dy = points[:, 0] - x, points[:, 1] - y
        in_base = ((np.abs(c * dx + s * dy) <= self.base_half[0]) & (np.abs(-s * dx + c * dy) <= self.base_half[1])
                   & (points[:, 2] <= self.base_top))
        return keep & ~in_base


def outside_spheres(points: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Mask of points outside all spheres; only points in the spheres' bounding box are tested."""
    keep = np.ones(len(points), dtype=bool)
    if len(points) == 0 or len(centres) == 0:
        return keep
    lo = (centres - radii[:, None]).min(axis=0)
    hi = (centres + radii[:, None]).max(axis=0)
    near = np.nonzero(np.all((points >= lo) & (points <= hi), axis=1))[0]
    if len(near) == 0:
        return keep
    d2 = ((points[near, None, :] - centres[None, :, :]) ** 2).sum(axis=-1)
    keep[near] = np.all(d2 > radii[None, :] ** 2, axis=1)
    return keep
