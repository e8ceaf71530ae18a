"""Robot self-filter: drop the points the cameras see of the robot's own body.

The body is the union of the collision spheres (centre P_j(q), radius r_j) of `RobotModel`, grown
by a margin, and of the base's collision boxes (`RobotModel.boxes`: body and rack, in the base frame
x, y, yaw = q[:3]; the body from the floor up, its wheels). The spheres are conservative where they
reach (anything inside them is the robot or a collision the controller must already prevent).
`LINK_SPHERES` add the arm's mount and shoulder joints for the filter (margin for their motors).
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
        self.box_lo = np.array([b.lo for b in robot.boxes]) - base_margin_m
        self.box_hi = np.array([b.hi for b in robot.boxes]) + base_margin_m
        on_floor = self.box_lo[:, 2] <= robot.params.base_clearance_m  # the body: its wheels below it too
        self.box_lo[on_floor, 2] = -np.inf

    def spheres(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (M×3) and grown radii (M,) at q: the collision spheres and `LINK_SPHERES`."""
        poses = self.robot.frame_poses(q, tuple(name for name, _ in LINK_SPHERES))
        links = np.array([poses[name][:3, 3] for name, _ in LINK_SPHERES])
        return np.concatenate([self.robot.sphere_centres(q), links]), self.radii

    def body(self, q: np.ndarray) -> RobotBody:
        """The robot's body at q: its spheres and its base boxes."""
        centres, radii = self.spheres(q)
        return RobotBody(centres, radii, np.asarray(q[:3], dtype=float), self.box_lo, self.box_hi)

    def outside(self, points: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Mask of the points (N×3) that lie outside the robot's body at q."""
        return self.body(q).outside(points)


@dataclass(frozen=True)
class RobotBody:
    """Collision spheres (centres M×3, radii M) and the base's boxes (pose x, y, yaw; corners lo, hi (B×3) in
    the base frame)."""

    centres: np.ndarray
    radii: np.ndarray
    base_pose: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray

    def outside(self, points: np.ndarray) -> np.ndarray:
        """Mask of the points (N×3) outside every sphere and outside the base's boxes."""
        keep = outside_spheres(points, self.centres, self.radii)
        x, y, yaw = self.base_pose
        c, s = np.cos(yaw), np.sin(yaw)
        dx, dy = points[:, 0] - x, points[:, 1] - y
        local = np.column_stack([c * dx + s * dy, -s * dx + c * dy, points[:, 2]])
        for lo, hi in zip(self.box_lo, self.box_hi, strict=True):
            keep &= ~np.all((local >= lo) & (local <= hi), axis=1)
        return keep


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
