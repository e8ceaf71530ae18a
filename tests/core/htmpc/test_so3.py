"""The SO(3) log of eq. (5) against pinocchio, and its Jacobian against finite differences."""

import numpy as np
import pinocchio as pin
import pytest

from core.htmpc.so3 import exp3, left_jacobian_inverse, log3


def random_rotations(n, rng, max_angle=np.pi):
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return axes * rng.uniform(0, max_angle, size=(n, 1))


def test_log3_matches_pinocchio_everywhere():
    rng = np.random.default_rng(0)
    phis = np.concatenate([random_rotations(300, rng), random_rotations(50, rng, 1e-5),
                           random_rotations(50, rng) * 0 + [[0, 0, np.pi - 1e-7]], np.zeros((1, 3))])
    R = exp3(phis)
    ours = log3(R)
    ref = np.array([pin.log3(r) for r in R])
    np.testing.assert_allclose(ours, ref, atol=1e-6)


def test_log3_hand_computed():
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90° about z
    np.testing.assert_allclose(log3(R), [0, 0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(log3(np.eye(3)), 0.0, atol=1e-15)


@pytest.mark.parametrize("angle", [1e-8, 0.3, 2.0, 3.0])
def test_left_jacobian_inverse(angle):
    rng = np.random.default_rng(1)
    phi = random_rotations(1, rng)[0] / np.pi * angle
    J = left_jacobian_inverse(phi)
    eps = 1e-6
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        fd = (log3(exp3(d) @ exp3(phi)) - log3(exp3(-d) @ exp3(phi))) / (2 * eps)
        np.testing.assert_allclose(J[:, i], fd, atol=1e-5)
