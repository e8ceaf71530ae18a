"""Symbolic (casadi) FK against pinocchio at 100 random configurations, values and Jacobians."""

import numpy as np
import pinocchio as pin
import pytest

from core.robot import SymbolicKinematics

N_SAMPLES = 100


@pytest.fixture(scope="module")
def sym(robot):
    return SymbolicKinematics(robot)


@pytest.fixture(scope="module")
def samples(robot):
    rng = np.random.default_rng(7)
    return [robot.random_q(rng) for _ in range(N_SAMPLES)]


def test_ee_pose_matches_pinocchio(robot, sym, samples):
    for q in samples:
        p, R = sym.ee_function(q)
        T = robot.ee_pose(q)
        np.testing.assert_allclose(np.array(p).ravel(), T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(np.array(R), T[:3, :3], atol=1e-9)


def test_sphere_centres_match_pinocchio(robot, sym, samples):
    for q in samples:
        P = np.array(sym.spheres_function(q)).T
        np.testing.assert_allclose(P, robot.sphere_centres(q), atol=1e-9)


def test_ee_jacobians_match_pinocchio(robot, sym, samples):
    for q in samples:
        Jp, JR = (np.array(m) for m in sym.ee_jacobian_function(q))
        J = robot.frame_jacobian(q, "ee")
        np.testing.assert_allclose(Jp, J[:3], atol=1e-9)
        R = robot.ee_pose(q)[:3, :3]
        for i in range(9):
            dR = JR[:, i].reshape(3, 3, order="F")  # casadi vec() is column-major
            np.testing.assert_allclose(dR, pin.skew(J[3:, i]) @ R, atol=1e-9)


def test_sphere_jacobians_match_pinocchio(robot, sym, samples):
    names = [f"sphere_{s.name}" for s in robot.spheres]
    for q in samples[:20]:
        J = np.array(sym.spheres_jacobian_function(q))
        for j, name in enumerate(names):
            np.testing.assert_allclose(J[3 * j: 3 * j + 3], robot.frame_jacobian(q, name)[:3], atol=1e-9)
