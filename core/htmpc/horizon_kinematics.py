"""Forward kinematics over the whole horizon in one casadi call (FK of the EE and of every collision
sphere, with Jacobians), so the SQP pays the call overhead once per iteration, not per node."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import casadi as ca
import numpy as np

from core.htmpc.buffered_function import BufferedFunction, compiled
from core.robot.model import RobotModel
from core.robot.symbolic_fk import SymbolicKinematics


@dataclass(frozen=True)
class HorizonKinematics:
    """Kinematics at K nodes: EE position p (K,3), rotation R (K,3,3), Jacobians Jp, Jw (K,3,9) in world
    axes; sphere centres P (K,M,3) and their Jacobians JP (K,M,3,9)."""

    p: np.ndarray
    R: np.ndarray
    Jp: np.ndarray
    Jw: np.ndarray
    P: np.ndarray
    JP: np.ndarray
    dvel_dq: np.ndarray | None = None
    """∂(J_P(q) v̄)/∂q (K,M,3,9) at the iterate's velocities v̄: how a sphere's velocity changes with q,
    needed to linearise dh/dt = ∇EDF^T J_P(q) v in q as well as in v (eq. 10)."""

    def dvel(self) -> np.ndarray:
        """`dvel_dq`, zero when it was not evaluated (velocities v̄ = 0)."""
        return self.dvel_dq if self.dvel_dq is not None else np.zeros_like(self.JP)


@cache
def _node_function(robot: RobotModel, jit: bool) -> ca.Function:
    """One node: [p (3), R row-major (9), Jp (3×9), Jw (3×9), P (M×3), JP (M×3×9), dvel_dq (M×3×9)], each
    block row-major and the whole column dense, so numpy reads each block with a reshape."""
    sym = SymbolicKinematics(robot)
    q = sym.q
    v = ca.SX.sym("v", q.shape[0])
    R, p = sym.frame("ee")
    dR = ca.jacobian(ca.vec(R), q)
    cols = []
    for j in range(q.shape[0]):
        S = ca.reshape(dR[:, j], 3, 3) @ R.T  # [ω_j]×
        cols.append(ca.vertcat(S[2, 1], S[0, 2], S[1, 0]))
    Jw = ca.horzcat(*cols)
    P = ca.vec(sym.sphere_centres())  # 3M, (xyz of sphere 0, sphere 1, ...)
    JP = ca.jacobian(P, q)
    dvel_dq = ca.jacobian(ca.jtimes(P, q, v), q)  # ∂(J_P v)/∂q as a Jacobian of a directional derivative
    flat = ca.vertcat(p, ca.vec(R.T), ca.vec(ca.jacobian(p, q).T), ca.vec(Jw.T), P, ca.vec(JP.T), ca.vec(dvel_dq.T))
    return compiled(ca.Function("kin", [q, v], [ca.densify(flat)]), jit)


class HorizonKinematicsEvaluator:
    """Evaluates `HorizonKinematics` for a (K, 9) array of configurations (and velocities) in one call."""

    def __init__(self, robot: RobotModel, n_nodes: int, jit: bool = True) -> None:
        self.robot = robot
        self.n_nodes = n_nodes
        self.n_spheres = len(robot.spheres)
        self._fn = BufferedFunction(_node_function(robot, jit).map(n_nodes, "serial"))
        M = self.n_spheres
        sizes = [3, 9, 27, 27, 3 * M, 27 * M, 27 * M]
        self._cuts = np.cumsum([0, *sizes])

    def __call__(self, q: np.ndarray, v: np.ndarray | None = None) -> HorizonKinematics:
        """Kinematics at q (K, 9); `v` (K, 9), zero if omitted, only enters `dvel_dq`."""
        K, M = self.n_nodes, self.n_spheres
        q_in, v_in = self._fn.inputs  # (9, K) column-major = (K, 9) row-major
        q_in[:] = np.asarray(q, float).ravel()
        v_in[:] = 0.0 if v is None else np.asarray(v, float).ravel()
        self._fn.evaluate()
        flat = self._fn.outputs[0].reshape(K, -1).copy()
        c = self._cuts
        return HorizonKinematics(
            p=flat[:, c[0]:c[1]], R=flat[:, c[1]:c[2]].reshape(K, 3, 3), Jp=flat[:, c[2]:c[3]].reshape(K, 3, 9),
            Jw=flat[:, c[3]:c[4]].reshape(K, 3, 9), P=flat[:, c[4]:c[5]].reshape(K, M, 3),
            JP=flat[:, c[5]:c[6]].reshape(K, M, 3, 9), dvel_dq=flat[:, c[6]:c[7]].reshape(K, M, 3, 9))
