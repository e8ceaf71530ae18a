"""The HTMPC's task costs J_l (eq. 5): pose-tracking errors of the base or the hand, mink/pink style. One
`TaskCost` interface, `compute_error(q, kin, ref)` and `compute_jacobian(q, kin, ref)` with the same arguments
for every cost, so the controller treats its levels alike (`TaskCost.reference` picks a cost's reference out of
`References`). "Task" alone names what an operator authors (`tasks/`, a task sequence of subtasks); a task
cost is what one subtask's reference becomes inside the controller.

Errors are e = reference − actual (position) and Log(R^T R_d) (orientation), one row per node; the
Jacobian is de/dq, so the Gauss-Newton model is e(q) ≈ e(q̄) + J (q − q̄).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.angles import wrap_angle
from core.htmpc.horizon_kinematics import HorizonKinematics
from core.htmpc.so3 import left_jacobian_inverse, log3
from core.types import BaseReference, EEReference, References


def _broadcast(a: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(a, float)
    return np.broadcast_to(a, (n, *a.shape[1:])) if a.shape[0] == 1 else a[:n]


@dataclass(frozen=True)
class Linearisation:
    """A task linearised over the horizon: e0 (K, m) at q̄, J (K, m, 9), weights (m,)."""

    name: str
    e0: np.ndarray
    J: np.ndarray
    weights: np.ndarray


class TaskCost:
    """A task of the hierarchy: its error e(q) over the horizon nodes and de/dq, from the configurations q (K, 9)
    and their kinematics `kin` (None is enough for a task with `needs_kinematics` False)."""

    name = ""
    needs_kinematics = True
    """Whether `compute_error` reads the FK (`kin`); the controller skips evaluating it otherwise."""
    linear_in_q = False
    """The error is affine in q, so its Gauss-Newton model, and a QP bound on it, are exact."""

    def __init__(self, weights: tuple[float, ...]) -> None:
        self.weights = np.asarray(weights, float)

    def reference(self, refs: References) -> BaseReference | EEReference | np.ndarray | None:
        """This task's reference in `refs` (None: the subtask does not use this task)."""
        raise NotImplementedError

    def compute_error(self, q: np.ndarray, kin: HorizonKinematics | None, ref) -> np.ndarray:
        """e (K, m) at each node."""
        raise NotImplementedError

    def compute_jacobian(self, q: np.ndarray, kin: HorizonKinematics | None, ref,
                         e: np.ndarray | None = None) -> np.ndarray:
        """de/dq (K, m, 9); `e` (the error at the same q) saves recomputing it where the Jacobian needs it."""
        raise NotImplementedError

    def linearise(self, q: np.ndarray, kin: HorizonKinematics | None, ref) -> Linearisation:
        e = self.compute_error(q, kin, ref)
        return Linearisation(self.name, e, self.compute_jacobian(q, kin, ref, e), self.weights[: e.shape[1]])


class BaseTaskCost(TaskCost):
    """Base pose task: e = [x_d − x, y_d − y, wrap(yaw_d − yaw)] (yaw dropped when the reference has none)."""

    name = "base"
    needs_kinematics = False
    linear_in_q = True

    def reference(self, refs: References) -> BaseReference | None:
        return refs.base

    def compute_error(self, q: np.ndarray, kin: HorizonKinematics | None, ref: BaseReference) -> np.ndarray:
        K = q.shape[0]
        xy = _broadcast(ref.xy, K) - q[:, :2]
        if ref.yaw is None:
            return xy
        dyaw = _broadcast(np.asarray(ref.yaw, float).reshape(-1, 1), K)[:, 0] - q[:, 2]
        return np.column_stack([xy, wrap_angle(dyaw)])

    def compute_jacobian(self, q: np.ndarray, kin: HorizonKinematics | None, ref: BaseReference,
                         e: np.ndarray | None = None) -> np.ndarray:
        m = 2 if ref.yaw is None else 3
        J = np.zeros((q.shape[0], m, 9))
        J[:, np.arange(m), np.arange(m)] = -1.0
        return J


class EETaskCost(TaskCost):
    """End-effector pose task: e = [p_d − p ; Log(R^T R_d)] (orientation dropped without a reference rotation).

    d Log(R^T R_d)/dq = −J_l^{-1}(e_r) R^T J_ω, from R(q + dq) ≈ exp([J_ω dq]×) R.
    """

    name = "ee"

    def reference(self, refs: References) -> EEReference | None:
        return refs.ee

    def compute_error(self, q: np.ndarray, kin: HorizonKinematics, ref: EEReference) -> np.ndarray:
        K = kin.p.shape[0]
        ep = _broadcast(ref.position, K) - kin.p
        if ref.rotation is None:
            return ep
        Rd = _broadcast(ref.rotation, K)
        er = log3(np.swapaxes(kin.R, -1, -2) @ Rd)
        return np.column_stack([ep, er])

    def compute_jacobian(self, q: np.ndarray, kin: HorizonKinematics, ref: EEReference,
                         e: np.ndarray | None = None) -> np.ndarray:
        Jp = -kin.Jp
        if ref.rotation is None:
            return Jp
        if e is None:
            e = self.compute_error(q, kin, ref)
        Jr = -left_jacobian_inverse(e[:, 3:]) @ np.swapaxes(kin.R, -1, -2) @ kin.Jw
        return np.concatenate([Jp, Jr], axis=1)


class PostureTaskCost(TaskCost):
    """Arm posture task: e = q_d − q over the six arm joints. In joint space the posture is one configuration, so
    holding it keeps the arm on its branch, where a hand pose alone is reached by up to eight (UR10) and a
    Gauss-Newton step near a singularity can switch between them."""

    name = "posture"
    needs_kinematics = False
    linear_in_q = True

    def reference(self, refs: References) -> np.ndarray | None:
        return refs.posture

    def compute_error(self, q: np.ndarray, kin: HorizonKinematics | None, ref: np.ndarray) -> np.ndarray:
        return _broadcast(np.asarray(ref, float).reshape(-1, 6), q.shape[0]) - q[:, 3:]

    def compute_jacobian(self, q: np.ndarray, kin: HorizonKinematics | None, ref: np.ndarray,
                         e: np.ndarray | None = None) -> np.ndarray:
        J = np.zeros((q.shape[0], 6, 9))
        J[:, np.arange(6), np.arange(3, 9)] = -1.0
        return J


def _yaw_rotations(yaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.zeros((len(yaw), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


class EEBaseFrameTaskCost(EETaskCost):
    """End-effector pose task in the base frame, for a hand held relative to the base while it drives:
    e = [p_d^b − R_ψ^T (p − t) ; Log((R_ψ^T R)^T R_d^b)], with t = (x, y, 0) and R_ψ the base yaw, at every node.

    A world target frozen at the current base pose would pull the base back to where it was; in the base frame
    the error depends on the arm joints only: d p^b/dq = R_ψ^T (J_p − J_t − [ẑ]×(p − t) e_ψ^T) and the angular
    Jacobian of R_ψ^T R is R_ψ^T (J_ω − ẑ e_ψ^T) (both vanish in x, y, ψ).
    """

    @staticmethod
    def _in_base(q: np.ndarray, kin: HorizonKinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """R_ψ (K,3,3), the EE position p^b (K,3) and rotation R^b (K,3,3) in the base frame."""
        Rb = _yaw_rotations(q[:, 2])
        d = kin.p - np.column_stack([q[:, :2], np.zeros(len(q))])
        RbT = np.swapaxes(Rb, -1, -2)
        return Rb, np.einsum("kij,kj->ki", RbT, d), RbT @ kin.R

    def compute_error(self, q: np.ndarray, kin: HorizonKinematics, ref: EEReference) -> np.ndarray:
        K = kin.p.shape[0]
        _, pb, Rb_ee = self._in_base(q, kin)
        ep = _broadcast(ref.position, K) - pb
        if ref.rotation is None:
            return ep
        er = log3(np.swapaxes(Rb_ee, -1, -2) @ _broadcast(ref.rotation, K))
        return np.column_stack([ep, er])

    def compute_jacobian(self, q: np.ndarray, kin: HorizonKinematics, ref: EEReference,
                         e: np.ndarray | None = None) -> np.ndarray:
        Rb, _, Rb_ee = self._in_base(q, kin)
        RbT = np.swapaxes(Rb, -1, -2)
        d = kin.p - np.column_stack([q[:, :2], np.zeros(len(q))])
        Jrel = kin.Jp.copy()
        Jrel[:, 0, 0] -= 1.0
        Jrel[:, 1, 1] -= 1.0
        Jrel[:, :, 2] -= np.column_stack([-d[:, 1], d[:, 0], np.zeros(len(q))])  # [ẑ]× d
        Jp = -RbT @ Jrel
        if ref.rotation is None:
            return Jp
        if e is None:
            e = self.compute_error(q, kin, ref)
        Jw = kin.Jw.copy()
        Jw[:, 2, 2] -= 1.0
        Jr = -left_jacobian_inverse(e[:, 3:]) @ np.swapaxes(Rb_ee, -1, -2) @ RbT @ Jw
        return np.concatenate([Jp, Jr], axis=1)
