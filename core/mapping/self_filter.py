"""Robot self-filter: drop the points the cameras see of the robot's own body.

The body is the union of the collision spheres (centre P_j(q), radius r_j) of `RobotModel`, grown
by a margin; the spheres are conservative (the base sphere is 0.55 m), so anything inside them is
either the robot or a collision the controller must already prevent.
"""

from __future__ import annotations

import numpy as np

from core.robot.model import RobotModel


class SelfFilter:
    """Masks points outside the robot's collision spheres at configuration q."""

    def __init__(self, robot: RobotModel, margin_m: float = 0.0) -> None:
        self.robot = robot
        self.radii = robot.sphere_radii + margin_m

    def spheres(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (M×3) and grown radii (M,) at q."""
        return self.robot.sphere_centres(q), self.radii

    def outside(self, points: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Mask of the points (N×3) that lie outside every (grown) collision sphere at q."""
        centres, radii = self.spheres(q)
        return outside_spheres(points, centres, radii)


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
