"""Collision spheres covering the arm (docs/method.md, "Settings": upper arm 4 × 0.15, forearm 3 × 0.15,
wrists 0.15–0.2, tool 0.15). One table; both FK flavours read it. The base and its rack are boxes
(`collision_boxes.py`).

The paper's table leaves parts of the UR10's collision meshes outside every sphere: its upper-arm
spheres sit on the link axis while the mesh's shoulder housing reaches 0.135 m to one side (5.5 cm out),
and nothing covered the shoulder (8 cm out) or the mount's edge (1 cm). Here the upper-arm spheres follow
the housing (y = −0.05) and the mount and shoulder have their own; `core/sim/collision_cover.py`
samples every MuJoCo collision geometry's surface against the union of spheres and boxes.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CollisionSphere:
    """A sphere of radius `radius_m` whose centre is `offset_m` in the frame of `link`."""

    name: str
    link: str
    offset_m: tuple[float, float, float]
    radius_m: float


SPHERES: tuple[CollisionSphere, ...] = (
    CollisionSphere("mount", "mobile_base", (0.27, 0.0, 0.67), 0.11),
    CollisionSphere("shoulder", "shoulder_link", (0.0, 0.0, 0.0), 0.15),
    CollisionSphere("upper_arm_0", "upper_arm_link", (0.0, -0.05, 0.03), 0.15),
    CollisionSphere("upper_arm_1", "upper_arm_link", (0.0, -0.05, 0.203), 0.15),
    CollisionSphere("upper_arm_2", "upper_arm_link", (0.0, -0.05, 0.377), 0.15),
    CollisionSphere("upper_arm_3", "upper_arm_link", (0.0, -0.05, 0.55), 0.15),
    CollisionSphere("forearm_0", "forearm_link", (0.0, 0.0, 0.05), 0.15),
    CollisionSphere("forearm_1", "forearm_link", (0.0, 0.0, 0.27), 0.15),
    CollisionSphere("forearm_2", "forearm_link", (0.0, 0.0, 0.49), 0.15),
    CollisionSphere("wrist_1", "wrist_1_link", (0.0, 0.0, 0.0), 0.15),
    CollisionSphere("wrist_2", "wrist_2_link", (0.0, 0.0, 0.0), 0.15),
    CollisionSphere("wrist_3", "wrist_3_link", (0.0, 0.0, 0.0), 0.2),
    CollisionSphere("tool", "ee", (0.1, 0.0, 0.0), 0.15),
)
"""The 13 spheres; `link` names a frame of `RobotModel` ('mobile_base' is the frame after the yaw joint)."""
