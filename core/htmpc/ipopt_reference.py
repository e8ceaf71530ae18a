"""Reference formulation: the same lexicographic problem as nonlinear programs solved by IPOPT.

Differences from the real-time controller are exactly the ones under study: exact nonlinear FK and
SO(3) log in the task errors and the collision rows (the EDF itself stays linearised at the iterate's
sphere centres, as the controller does, since an interpolant of the grid is impractical in casadi),
and IPOPT iterates to convergence. Used by tests for accuracy and by `bench/htmpc_solve.py` for the
speed ratio and the cost gap.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from core.htmpc.box_barrier import BoxBarrier
from core.htmpc.collision_constraint import DistanceField
from core.htmpc.horizon_kinematics import HorizonKinematicsEvaluator
from core.htmpc.htmpc import collision_row_names, slack_groups
from core.htmpc.level_problem import lex_limits, lex_tolerances
from core.params import HTMPCParams
from core.robot.model import RobotModel
from core.robot.symbolic_fk import SymbolicKinematics
from core.types import References, RobotState


def _log3_sx(E: ca.SX) -> ca.SX:
    """Rotation vector of E with atan2 (smooth derivatives near zero; fine away from π)."""
    w = 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])
    s = ca.sqrt(ca.dot(w, w) + 1e-18)
    c = (ca.trace(E) - 1.0) / 2.0
    theta = ca.atan2(s, c)
    return w * ca.if_else(s > 1e-6, theta / s, 1.0 + s**2 / 6.0)


@dataclass(frozen=True)
class ReferenceResult:
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    level_costs: tuple[float, ...]
    level_ms: tuple[float, ...]
    success: bool
    compared_costs: tuple[float, ...] = ()
    eval_ms: tuple[float, ...] = ()
    """Per level, the time IPOPT spent in casadi's (interpreted) function and derivative evaluations;
    level_ms − eval_ms is IPOPT's own work, a lower bound for a compiled formulation."""
    level_objectives: tuple[float, ...] = ()
    """J_l + J_aux of IPOPT's level-l solution (without the slack penalty)."""
    compared_objectives: tuple[float, ...] = ()
    """J_l + J_aux of the compared level-l solutions."""
    compared_violations: tuple[float, ...] = ()
    """Largest violation of IPOPT's (exact-kinematics) collision rows by each compared solution."""
    level_task_costs: tuple[float, ...] = ()
    """J_l alone (Σ dt ½‖e_l‖²_Q) of IPOPT's level-l solution: what (7c) hands on to later levels."""
    compared_task_costs: tuple[float, ...] = ()
    """J_l alone of the compared level-l solutions."""


class IpoptReference:
    """Solves the levels of one control step with IPOPT (exact kinematics)."""

    def __init__(self, robot: RobotModel, params: HTMPCParams | None = None, tol: float = 1e-8) -> None:
        self.robot = robot
        self.params = params or HTMPCParams()
        self.tol = tol
        self.sym = SymbolicKinematics(robot)
        self.kin = HorizonKinematicsEvaluator(robot, self.params.N + 1)
        self.boxes = BoxBarrier(robot.boxes, self.params.box_iterations)
        self.groups = slack_groups(collision_row_names(robot, self.boxes), self.params.slack_groups)
        self.radii = np.concatenate([robot.sphere_radii, np.zeros(self.boxes.n_rows)])
        """Per collision row: the spheres, then the base boxes' sides (points at the warm start's closest points)."""
        self._cache: dict[tuple, tuple] = {}

    # --- symbolic pieces --------------------------------------------------------------------------

    def _errors(self, name: str, q: ca.SX, ref_p: ca.SX, ref_R: ca.SX | None, in_base: bool = False) -> ca.SX:
        """The task's error at q; `in_base`: the EE pose in the base frame (`EEBaseFrameTaskCost`)."""
        if name == "posture":  # here ref_R's first six rows hold the arm joints' reference
            assert ref_R is not None
            return ref_R[:6] - q[3:]
        if name == "base":
            e = ref_p[:2] - q[:2]
            if ref_R is not None:  # here ref_R holds the yaw reference
                d = ref_R - q[2]
                e = ca.vertcat(e, ca.atan2(ca.sin(d), ca.cos(d)))
            return e
        R, p = self.sym.frame("ee")
        Rq = ca.substitute(R, self.sym.q, q)
        pq = ca.substitute(p, self.sym.q, q)
        if in_base:
            c, s = ca.cos(q[2]), ca.sin(q[2])
            RpsiT = ca.vertcat(ca.horzcat(c, s, 0), ca.horzcat(-s, c, 0), ca.horzcat(0, 0, 1))
            pq = RpsiT @ (pq - ca.vertcat(q[0], q[1], 0))
            Rq = RpsiT @ Rq
        e = ref_p - pq
        if ref_R is not None:
            e = ca.vertcat(e, _log3_sx(Rq.T @ ref_R))
        return e

    def _build(self, levels: tuple[str, ...], has_rot: dict[str, bool], level: int, with_edf: bool,
               ee_in_base: bool = False):
        p, N, M = self.params, self.params.N, len(self.radii)
        R = self.boxes.n_rows
        ns = int(self.groups.max()) + 1
        X = ca.SX.sym("X", 18, N + 1)
        U = ca.SX.sym("U", 9, N)
        S = ca.SX.sym("S", ns, N - 1)
        x0 = ca.SX.sym("x0", 18)
        refs = {name: (ca.SX.sym(f"p_{name}", 3, N + 1), ca.SX.sym(f"R_{name}", 9, N + 1)) for name in levels}
        dbar = ca.SX.sym("dbar", M, N - 1)
        grad = ca.SX.sym("grad", 3 * M, N - 1)
        Pbar = ca.SX.sym("Pbar", 3 * M, N - 1)
        estar = {name: (ca.SX.sym(f"elo_{name}", 6, N), ca.SX.sym(f"ehi_{name}", 6, N)) for name in levels[:level]}
        box_local = ca.SX.sym("box_local", 3 * R, N - 1)
        local = ca.SX.sym("local", 3 * R)
        q_sym = self.sym.q
        c, s = ca.cos(q_sym[2]), ca.sin(q_sym[2])
        box_pts = [ca.vertcat(q_sym[0] + c * local[3 * r] - s * local[3 * r + 1],
                              q_sym[1] + s * local[3 * r] + c * local[3 * r + 1], local[3 * r + 2]) for r in range(R)]
        P_fn = ca.Function("P", [q_sym, local], [ca.vertcat(ca.vec(self.sym.sphere_centres()), *box_pts)])
        dt = p.dt_s
        W = {"base": np.array(p.Q_base), "ee": np.array(p.Q_ee), "posture": np.array(p.Q_posture)}

        def err(name, k):
            ref_p, ref_R = refs[name]
            if name == "posture":
                return self._errors(name, X[:9, k], ref_p[:, k], ref_R[:, k])
            if name == "base":
                rot = ref_R[0, k] if has_rot[name] else None
                return self._errors(name, X[:9, k], ref_p[:, k], rot)
            rot = ca.reshape(ref_R[:, k], 3, 3) if has_rot[name] else None
            return self._errors(name, X[:9, k], ref_p[:, k], rot, ee_in_base)

        cost, task = 0, 0
        g, lbg, ubg = [], [], []
        names = list(levels) if p.hierarchy == "weighted" else [levels[level]]
        for k in range(1, N + 1):
            q, v = X[:9, k], X[9:, k]
            for name in names:
                e = err(name, k)
                w = W[name][: e.shape[0]]
                task += dt * 0.5 * ca.sum1(w * e**2)
                cost += dt * 0.5 * ca.sum1(w * e**2)
                edot = ca.jtimes(e, X[:9, k], v)
                cost += dt * 0.5 * p.Q_edot * ca.sum1(w * edot**2)
            cost += dt * 0.5 * p.Q_x * ca.sumsqr(v)
            for name in levels[:level]:
                e = err(name, k)
                m = e.shape[0]
                lo, hi = estar[name]
                g.append(e - hi[:m, k - 1])
                lbg.append(-np.inf * np.ones(m))
                ubg.append(np.zeros(m))
                g.append(e - lo[:m, k - 1])
                lbg.append(np.zeros(m))
                ubg.append(np.inf * np.ones(m))
        for k in range(N):
            cost += dt * 0.5 * p.Q_u * ca.sumsqr(U[:, k])
            qn = X[:9, k] + dt * X[9:, k] + 0.5 * dt * dt * U[:, k]
            vn = X[9:, k] + dt * U[:, k]
            g.append(X[:, k + 1] - ca.vertcat(qn, vn))
            lbg.append(np.zeros(18))
            ubg.append(np.zeros(18))
            g.append(ca.sumsqr(X[9:11, k + 1]))  # the base's planar speed (the QP: a polygon inside this circle)
            lbg.append(-np.inf * np.ones(1))
            ubg.append(np.full(1, self.robot.limits.planar_speed ** 2))
        objective = cost  # J_l + J_aux: what the comparison uses (the slack penalty is exact-penalty bookkeeping)
        cost += ca.sum1(ca.sum2(p.slack_linear * S + p.slack_quadratic * S**2))
        if with_edf:
            for k in range(1, N):
                q, v = X[:9, k], X[9:, k]
                Pq = P_fn(q, box_local[:, k - 1])
                JP = ca.jacobian(Pq, q)
                for j in range(M):
                    gj = grad[3 * j:3 * j + 3, k - 1]
                    h = dbar[j, k - 1] + ca.dot(gj, Pq[3 * j:3 * j + 3] - Pbar[3 * j:3 * j + 3, k - 1]) \
                        - self.radii[j] - p.delta_safe_m
                    if p.constraint == "cbf":
                        hdot = ca.dot(gj, JP[3 * j:3 * j + 3, :] @ v)
                        g.append(hdot + p.gamma * h + S[self.groups[j], k - 1])
                    else:
                        g.append(h + S[self.groups[j], k - 1])
                    lbg.append(np.zeros(1))
                    ubg.append(np.inf * np.ones(1))
        z = ca.vertcat(ca.vec(X), ca.vec(U), ca.vec(S))
        par = ca.vertcat(x0, *[ca.vertcat(ca.vec(a), ca.vec(b)) for a, b in refs.values()], ca.vec(dbar),
                         ca.vec(grad), ca.vec(Pbar), ca.vec(box_local),
                         *[ca.vertcat(ca.vec(lo), ca.vec(hi)) for lo, hi in estar.values()])
        g.insert(0, X[:, 0] - x0)
        lbg.insert(0, np.zeros(18))
        ubg.insert(0, np.zeros(18))
        nlp = {"x": z, "p": par, "f": cost, "g": ca.vertcat(*g)}
        opts = {"ipopt": {"print_level": 0, "tol": self.tol, "max_iter": 300, "warm_start_init_point": "yes",
                          "mu_init": 1e-3, "sb": "yes"}, "print_time": False}
        solver = ca.nlpsol("reference", "ipopt", nlp, opts)
        cost_fn = ca.Function("cost", [z, par], [cost, objective, task])
        rows = g[-(M * (N - 1)):] if with_edf else []
        rows_fn = ca.Function("collision_rows", [z, par], [ca.vertcat(*rows) if rows else ca.DM.zeros(0)])
        errs = ca.Function("errors", [z, par], [ca.vertcat(*[ca.vec(ca.horzcat(*[
            ca.vertcat(err(name, k), ca.DM.zeros(6 - err(name, k).shape[0])) for k in range(1, N + 1)]))
            for name in levels])])
        return solver, errs, np.concatenate(lbg), np.concatenate(ubg), cost_fn, rows_fn

    # --- solve ------------------------------------------------------------------------------------

    def solve(self, state: RobotState, refs: References, edf: DistanceField | None,
              q_guess: np.ndarray, v_guess: np.ndarray, a_guess: np.ndarray,
              compare: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]] = ()) -> ReferenceResult:
        """All levels of one step, warm-started from a guess (e.g. the controller's warm start).

        `compare[l]` = (q, v, a) of another solver's level-l solution (the controller's; the last one is
        reused for further levels): its level-l objective is evaluated with the same nonlinear functions
        (slacks at their smallest feasible values) into `compared_costs`.
        """
        compared: list[float] = []
        p, N = self.params, self.params.N
        ee_in_base = refs.ee is not None and refs.ee.frame == "base"
        given = {"base": refs.base, "ee": refs.ee, "posture": refs.posture}
        order = tuple(n for n in refs.order if given[n] is not None)
        has_rot = {"base": refs.base is not None and refs.base.yaw is not None,
                   "ee": refs.ee is not None and refs.ee.rotation is not None, "posture": True}
        ns = int(self.groups.max()) + 1
        kin = self.kin(q_guess)
        M = len(self.radii)
        if edf is not None:
            local = self.boxes.local_points(q_guess[1:N], edf)
            Pbar = np.concatenate([kin.P[1:N], self.boxes.points(q_guess[1:N], v_guess[1:N], edf).P], axis=1)
            dbar, grad = edf.distance(Pbar), edf.gradient(Pbar)
        else:
            local = np.zeros((N - 1, self.boxes.n_rows, 3))
            Pbar, dbar, grad = np.zeros((N - 1, M, 3)), np.full((N - 1, M), 10.0), np.zeros((N - 1, M, 3))
        ref_par = []
        for name in order:  # `order` names only tasks with a reference
            if name == "base":
                assert refs.base is not None
                xy = np.broadcast_to(refs.base.xy, (N + 1, 2))
                pos = np.column_stack([xy, np.zeros(N + 1)])
                yaw = np.zeros((N + 1, 9))
                if refs.base.yaw is not None:
                    yaw[:, 0] = np.broadcast_to(np.asarray(refs.base.yaw), (N + 1,))
                ref_par.append(np.concatenate([pos.ravel(), yaw.ravel()]))
            elif name == "posture":
                assert refs.posture is not None
                joints = np.zeros((N + 1, 9))
                joints[:, :6] = np.broadcast_to(np.asarray(refs.posture, float).reshape(-1, 6), (N + 1, 6))
                ref_par.append(np.concatenate([np.zeros((N + 1) * 3), joints.ravel()]))
            else:
                assert refs.ee is not None
                pos = np.broadcast_to(refs.ee.position, (N + 1, 3))
                rot = np.zeros((N + 1, 9))
                if refs.ee.rotation is not None:
                    rot = np.broadcast_to(refs.ee.rotation, (N + 1, 3, 3)).transpose(0, 2, 1).reshape(N + 1, 9)
                ref_par.append(np.concatenate([pos.ravel(), rot.ravel()]))
        x0 = np.concatenate([state.q, self.robot.limits.clip_velocity(state.v)])
        z0 = np.concatenate([np.column_stack([q_guess, v_guess]).ravel(), a_guess.ravel(), np.zeros(ns * (N - 1))])
        lbz, ubz = self._bounds(x0, ns)
        estars: list[tuple[np.ndarray, np.ndarray]] = []
        costs, times, evals, objectives, compared_obj, violations = [], [], [], [], [], []
        tasks, compared_task = [], []
        levels = 1 if p.hierarchy == "weighted" else len(order)
        z = z0
        success = True
        for level in range(levels):
            key = (order, tuple(sorted(has_rot.items())), level, edf is not None, p.hierarchy, ee_in_base)
            if key not in self._cache:
                self._cache[key] = self._build(order, has_rot, level, edf is not None, ee_in_base)
            solver, errs, lbg, ubg, cost_fn, rows_fn = self._cache[key]
            par = np.concatenate([x0, *ref_par, dbar.ravel(), grad.ravel(), Pbar.ravel(), local.ravel(),
                                  *[np.concatenate([lo.ravel(order="F"), hi.ravel(order="F")]) for lo, hi in estars]])
            t0 = time.perf_counter()
            out = solver(x0=z, p=par, lbx=lbz, ubx=ubz, lbg=lbg, ubg=ubg)
            times.append((time.perf_counter() - t0) * 1e3)
            stats = solver.stats()
            success &= bool(stats["success"])
            evals.append(1e3 * sum(v for k, v in stats.items() if k.startswith("t_wall_nlp_")))
            z = np.asarray(out["x"]).ravel()
            costs.append(float(out["f"]))
            _, objective, task = cost_fn(z, par)
            objectives.append(float(objective))
            tasks.append(float(task))
            if compare:
                zc, violation = self._with_min_slacks(compare[min(level, len(compare) - 1)], ns, rows_fn, par)
                full, objective, task = cost_fn(zc, par)
                compared.append(float(full))
                compared_obj.append(float(objective))
                compared_task.append(float(task))
                violations.append(violation)
            e_all = np.asarray(errs(z, par)).ravel().reshape(len(order), N, 6)
            lo, hi = lex_limits(e_all[level], lex_tolerances(p))
            estars.append((lo.T, hi.T))
        n_x = 18 * (N + 1)
        X = z[:n_x].reshape(N + 1, 18)
        U = z[n_x:n_x + 9 * N].reshape(N, 9)
        return ReferenceResult(X[:, :9], X[:, 9:], U, tuple(costs), tuple(times), success, tuple(compared),
                               tuple(evals), tuple(objectives), tuple(compared_obj), tuple(violations), tuple(tasks),
                               tuple(compared_task))

    def _with_min_slacks(self, traj: tuple[np.ndarray, np.ndarray, np.ndarray], ns: int, rows_fn: ca.Function,
                         par: np.ndarray) -> tuple[np.ndarray, float]:
        """The trajectory as an NLP point with the smallest slacks its collision rows need, and the
        largest of those (the trajectory's violation of the exact rows)."""
        q, v, a = traj
        N = self.params.N
        z = np.concatenate([np.column_stack([q, v]).ravel(), a.ravel(), np.zeros(ns * (N - 1))])
        rows = np.asarray(rows_fn(z, par)).ravel()
        if rows.size:
            need = np.maximum(0.0, -rows.reshape(N - 1, -1))
            slack = np.zeros((N - 1, ns))
            for g in range(ns):
                slack[:, g] = need[:, self.groups == g].max(axis=1)
            z[-ns * (N - 1):] = slack.ravel()
            return z, float(need.max())
        return z, 0.0

    def _bounds(self, x0: np.ndarray, ns: int) -> tuple[np.ndarray, np.ndarray]:
        p, N, lim = self.params, self.params.N, self.robot.limits
        lb_x = np.tile(np.concatenate([lim.q_min, -lim.v_max]), (N + 1, 1))
        ub_x = np.tile(np.concatenate([lim.q_max, lim.v_max]), (N + 1, 1))
        widened = np.maximum(lim.v_max, np.abs(x0[9:]) - lim.a_max * p.dt_s + 1e-6)
        lb_x[1, 9:], ub_x[1, 9:] = -widened, widened
        lb_x[0], ub_x[0] = x0, x0
        lb_u = np.tile(-lim.a_max, N)
        ub_u = np.tile(lim.a_max, N)
        return (np.concatenate([lb_x.ravel(), lb_u, np.zeros(ns * (N - 1))]),
                np.concatenate([ub_x.ravel(), ub_u, np.full(ns * (N - 1), np.inf)]))
