"""The controller's collision geometry (spheres and base boxes) covers every robot collision geom of the
MuJoCo model: surfaces sampled every centimetre, link by link, in many configurations."""

import numpy as np
import pytest

from core.robot.model import READY_Q
from core.sim.collision_cover import cover_gaps, outside_distance, robot_surface_samples


def test_every_robot_geom_is_sampled(world):
    samples = robot_surface_samples(world)
    assert {"base_body", "base_rack", "geom_shoulder_link", "geom_upper_arm_link", "geom_wrist_3_link"} <= set(samples)
    assert all(len(p) > 200 for p in samples.values())


def test_no_surface_point_lies_outside_the_controllers_geometry(world, robot):
    rng = np.random.default_rng(11)
    configurations = [READY_Q] + [robot.random_q(rng) for _ in range(8)]
    gaps = cover_gaps(world, robot, configurations)
    assert max(gaps.values()) == 0.0, {k: v for k, v in gaps.items() if v > 0}


def test_outside_distance_sees_a_point_beyond_the_base_corner(robot):
    q = READY_Q.copy()
    q[:3] = (1.0, 2.0, np.pi / 2)  # the base's +x corner (0.48, 0.395) is now at world (1 − 0.395, 2 + 0.48)
    corner = np.array([[1.0 - 0.395, 2.0 + 0.48, 0.2]])
    assert outside_distance(robot, q, corner)[0] == 0.0
    assert outside_distance(robot, q, corner + [[-0.03, 0.04, 0.0]])[0] == pytest.approx(0.05)
