"""Collision spheres covering base and arm (METHOD.md: base 0.55, rack 2 × 0.5, upper arm 4 × 0.15,
forearm 3 × 0.15, wrists 0.15–0.2, tool 0.15). One table; both FK flavours read it."""

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
    CollisionSphere("base", "mobile_base", (0.0, 0.0, 0.25), 0.55),
    CollisionSphere("rack_low", "mobile_base", (-0.2, 0.0, 0.55), 0.5),
    CollisionSphere("rack_high", "mobile_base", (-0.2, 0.0, 0.95), 0.5),
    CollisionSphere("upper_arm_0", "upper_arm_link", (0.0, 0.0, 0.08), 0.15),
    CollisionSphere("upper_arm_1", "upper_arm_link", (0.0, 0.0, 0.25), 0.15),
    CollisionSphere("upper_arm_2", "upper_arm_link", (0.0, 0.0, 0.42), 0.15),
    CollisionSphere("upper_arm_3", "upper_arm_link", (0.0, 0.0, 0.59), 0.15),
    CollisionSphere("forearm_0", "forearm_link", (0.0, 0.0, 0.05), 0.15),
    CollisionSphere("forearm_1", "forearm_link", (0.0, 0.0, 0.27), 0.15),
    CollisionSphere("forearm_2", "forearm_link", (0.0, 0.0, 0.49), 0.15),
    CollisionSphere("wrist_1", "wrist_1_link", (0.0, 0.0, 0.0), 0.15),
    CollisionSphere("wrist_2", "wrist_2_link", (0.0, 0.0, 0.0), 0.15),
    CollisionSphere("wrist_3", "wrist_3_link", (0.0, 0.0, 0.0), 0.2),
    CollisionSphere("tool", "ee", (0.1, 0.0, 0.0), 0.15),
)
"""The 14 spheres; `link` names a frame of `RobotModel` ('mobile_base' is the frame after the yaw joint)."""
