"""The base boxes' barrier: closest points found by alternating projections against a dense sampling of
the boxes, and their Jacobians against finite differences."""

import numpy as np
import pytest

from core.htmpc.box_barrier import BoxBarrier
from core.robot.model import READY_Q
from core.scene import Box
from core.sim.collision_cover import _box_surface
from core.sim.ground_truth import ground_truth_edf


def base_q(x, y, yaw):
    q = READY_Q.copy()
    q[:3] = x, y, yaw
    return q


def sampled_min(robot, edf, q, box):
    """min of the EDF over a 1 cm sampling of a base box's surface at configuration q."""
    c, s = np.cos(q[2]), np.sin(q[2])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    surface = _box_surface(np.array(box.half_m), 0.01) + box.centre_m
    return float(edf.distance(surface @ R.T + [q[0], q[1], 0.0]).min())


@pytest.mark.parametrize("yaw", [0.0, 0.4, -2.0])
def test_closest_points_match_a_dense_sampling(robot, yaw):
    barrier = BoxBarrier(robot.boxes, iterations=3)
    edf = ground_truth_edf([Box("ahead_left", (0.95, 0.75, 0.3), yaw=0.3), Box("overhead", (-0.3, -0.5, 1.3)),
                            Box("behind", (-1.2, 0.1, 0.3))], np.zeros(2))
    q = base_q(0.0, 0.0, yaw)
    pts = barrier.points(q[None], np.zeros((1, 9)), edf)
    for b, box in enumerate(robot.boxes):
        found = edf.distance(pts.P[0, 4 * b:4 * b + 4]).min()
        assert found == pytest.approx(sampled_min(robot, edf, q, box), abs=0.005), box.name


def test_rows_per_side_see_both_walls_of_a_corridor(robot):
    barrier = BoxBarrier(robot.boxes)
    edf = ground_truth_edf([Box("left", (0.0, 0.8, 0.3), (3.0, 0.6, 0.6)),
                            Box("right", (0.0, -0.8, 0.3), (3.0, 0.6, 0.6))], np.zeros(2))
    pts = barrier.points(base_q(0.0, 0.0, 0.0)[None], np.zeros((1, 9)), edf)
    d = dict(zip(barrier.names, edf.distance(pts.P[0]), strict=True))
    assert d["base_body_left"] == pytest.approx(0.5 - 0.395, abs=0.01)
    assert d["base_body_right"] == pytest.approx(0.5 - 0.395, abs=0.01)


def test_point_jacobians_match_finite_differences(robot):
    barrier = BoxBarrier(robot.boxes)
    edf = ground_truth_edf([Box("a", (1.1, 0.4, 0.3))], np.zeros(2))
    q = base_q(0.1, -0.2, 0.3)
    v = np.zeros(9)
    v[2] = 0.7
    pts = barrier.points(q[None], v[None], edf)
    local = barrier.local_points(q[None], edf)[0]

    def world(qq):
        c, s = np.cos(qq[2]), np.sin(qq[2])
        return local @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) + [qq[0], qq[1], 0.0]

    eps = 1e-6
    for j in range(3):
        dq = np.zeros(9)
        dq[j] = eps
        np.testing.assert_allclose(pts.JP[0, :, :, j], (world(q + dq) - world(q - dq)) / (2 * eps), atol=1e-8)
    # ∂(J_P v)/∂yaw: the body point's velocity turns with the base
    def velocity(qq):
        return (world(qq + eps * v) - world(qq - eps * v)) / (2 * eps)

    dq = np.zeros(9)
    dq[2] = 1e-4
    fd = (velocity(q + dq) - velocity(q - dq)) / 2e-4
    np.testing.assert_allclose(pts.dvel_dq[0, :, :, 2], fd, atol=1e-5)
