"""TaskCost errors of eq. (5) and their Gauss-Newton Jacobians against hand values and finite differences."""

import numpy as np
import pinocchio as pin

from core.htmpc.horizon_kinematics import HorizonKinematicsEvaluator
from core.htmpc.task_costs import BaseTaskCost, EEBaseFrameTaskCost, EETaskCost, PostureTaskCost
from core.types import BaseReference, EEReference, References


def _jacobian_matches_finite_differences(robot, task, q0: np.ndarray, ref: EEReference) -> np.ndarray:
    """Assert the cost's Jacobian at q0 against central differences (step 1e-6, to 1e-6); returns it."""
    ev = HorizonKinematicsEvaluator(robot, 1)
    J = task.compute_jacobian(q0[None], ev(q0[None]), ref)[0]
    eps = 1e-6
    for j in range(9):
        dq = np.zeros(9)
        dq[j] = eps
        plus = task.compute_error((q0 + dq)[None], ev((q0 + dq)[None]), ref)[0]
        minus = task.compute_error((q0 - dq)[None], ev((q0 - dq)[None]), ref)[0]
        np.testing.assert_allclose(J[:, j], (plus - minus) / (2 * eps), atol=1e-6)
    return J


def test_base_error_hand_computed():
    task = BaseTaskCost((1.0, 1.0, 0.5))
    q = np.zeros((2, 9))
    q[1, :3] = [1.0, 2.0, 3.0]
    ref = BaseReference(xy=np.array([[2.0, 0.0]]), yaw=np.array([-3.0]))
    e = task.compute_error(q, None, ref)
    np.testing.assert_allclose(e[0], [2.0, 0.0, -3.0])
    np.testing.assert_allclose(e[1], [1.0, -2.0, -6.0 + 2 * np.pi])  # −6 rad wrapped into (−π, π]
    J = task.compute_jacobian(q, None, ref)
    np.testing.assert_allclose(J[0, :, :3], -np.eye(3))
    assert task.compute_error(q, None, BaseReference(xy=np.array([[2.0, 0.0]]))).shape == (2, 2)


def test_ee_error_uses_exact_log(robot):
    rng = np.random.default_rng(2)
    q = np.array([robot.random_q(rng) for _ in range(4)])
    kin = HorizonKinematicsEvaluator(robot, 4)(q)
    Rd = pin.utils.rpyToMatrix(0.3, -1.0, 2.5)
    pd = np.array([1.0, -0.5, 0.8])
    e = EETaskCost((1,) * 6).compute_error(q, kin, EEReference(pd[None], Rd[None]))
    for k in range(4):
        T = robot.ee_pose(q[k])
        np.testing.assert_allclose(e[k, :3], pd - T[:3, 3], atol=1e-12)
        np.testing.assert_allclose(e[k, 3:], pin.log3(T[:3, :3].T @ Rd), atol=1e-9)


def test_ee_jacobian_matches_finite_differences(robot):
    q0 = robot.random_q(np.random.default_rng(3))
    ref = EEReference(np.array([[0.9, 0.2, 1.0]]), pin.utils.rpyToMatrix(0.1, 0.4, -0.7)[None])
    _jacobian_matches_finite_differences(robot, EETaskCost((1,) * 6), q0, ref)


def test_base_frame_ee_error_is_the_pose_relative_to_the_base(robot):
    rng = np.random.default_rng(4)
    q = np.array([robot.random_q(rng) for _ in range(3)])
    kin = HorizonKinematicsEvaluator(robot, 3)(q)
    pd, Rd = np.array([0.3, -0.6, 0.9]), pin.utils.rpyToMatrix(0.0, 0.2, -1.5)
    e = EEBaseFrameTaskCost((1,) * 6).compute_error(q, kin, EEReference(pd[None], Rd[None], frame="base"))
    for k in range(3):
        T_base = robot.frame_pose(q[k], "mobile_base")
        T_rel = np.linalg.inv(T_base) @ robot.ee_pose(q[k])
        np.testing.assert_allclose(e[k, :3], pd - T_rel[:3, 3], atol=1e-12)
        np.testing.assert_allclose(e[k, 3:], pin.log3(T_rel[:3, :3].T @ Rd), atol=1e-9)
    moved = q.copy()
    moved[:, :3] += [1.5, -2.0, 0.7]  # the base drives and turns: the base-frame error does not change
    e2 = EEBaseFrameTaskCost((1,) * 6).compute_error(moved, HorizonKinematicsEvaluator(robot, 3)(moved),
                                                     EEReference(pd[None], Rd[None], frame="base"))
    np.testing.assert_allclose(e2, e, atol=1e-9)


def test_base_frame_ee_jacobian_matches_finite_differences(robot):
    q0 = robot.random_q(np.random.default_rng(5))
    for rot in (None, pin.utils.rpyToMatrix(0.1, 0.4, -0.7)[None]):
        ref = EEReference(np.array([[0.5, 0.2, 1.0]]), rot, frame="base")
        J = _jacobian_matches_finite_differences(robot, EEBaseFrameTaskCost((1,) * 6), q0, ref)
        np.testing.assert_allclose(J[:, :3], 0.0, atol=1e-9)  # the base's own joints do not move it


def test_every_task_takes_the_same_arguments_and_picks_its_own_reference(robot):
    """One interface: the controller calls compute_error / compute_jacobian / linearise alike on every level."""
    rng = np.random.default_rng(5)
    q = np.array([robot.random_q(rng) for _ in range(3)])
    kin = HorizonKinematicsEvaluator(robot, 3)(q)
    base = BaseReference(xy=np.array([[1.0, -1.0]]), yaw=np.array([0.3]))
    world = EEReference(np.array([[0.8, 0.1, 1.0]]), np.eye(3)[None])
    in_base = EEReference(np.array([[0.5, 0.0, 0.9]]), np.eye(3)[None], frame="base")
    cases = ((BaseTaskCost((1.0,) * 3), base), (EETaskCost((1.0,) * 6), world),
             (EEBaseFrameTaskCost((1.0,) * 6), in_base))
    for task, ref in cases:
        refs = References(order=("base", "ee"), base=base, ee=ref if task.name == "ee" else None)
        assert task.reference(refs) is ref
        e = task.compute_error(q, kin, ref)
        J = task.compute_jacobian(q, kin, ref)
        lin = task.linearise(q, kin, ref)
        np.testing.assert_array_equal(lin.e0, e)
        np.testing.assert_array_equal(lin.J, J)
        assert J.shape == (3, e.shape[1], 9) and lin.weights.shape == (e.shape[1],)
    assert BaseTaskCost((1.0,) * 3).compute_error(q, None, base).shape == (3, 3)  # the base task needs no FK


def test_posture_error_and_jacobian_are_the_arm_joints():
    task = PostureTaskCost((0.5,) * 6)
    q = np.array([[1.0, 2.0, 0.3, 0.1, -1.5, 2.0, -0.1, 1.5, 3.0], [0.0, 0.0, 0.0, 0.2, -1.6, 2.2, -0.2, 1.6, 3.1]])
    ref = np.array([[0.0, -1.6, 2.2, -0.2, 1.5708, 3.1416]])
    np.testing.assert_allclose(task.compute_error(q, None, ref), ref - q[:, 3:])  # the base plays no part
    J = task.compute_jacobian(q, None, ref)
    np.testing.assert_allclose(J[:, :, :3], 0.0)
    np.testing.assert_allclose(J[0, :, 3:], -np.eye(6))
    assert task.reference(References(order=("posture",), posture=ref)) is ref

