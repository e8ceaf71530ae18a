"""Assemble one level's QP (docs/method.md, eqs. 6–8) as non-zero vectors of the structured layout.

Level l minimises  J_l + J_aux  over the horizon, with
  J_l   = Σ_k dt · ½‖e_l,k‖²_Q                  (task cost, Gauss-Newton model e ≈ e0 + J (q − q̄))
  J_aux = Σ_k dt · (½ Q_edot‖J v_k‖²_Q + ½ Q_x‖v_k‖² + ½ Q_u‖a_k‖²)   (8: conditioning only)
  slack = Σ (slack_linear · s + slack_quadratic · s²)
subject to the dynamics, box bounds on q, v, a, the collision rows (eq. 10, softened) and, for every
earlier level i, |e_i,k| ≤ |e_i,k*| + tol_k (7c, hard).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.htmpc.collision_constraint import CollisionRows, StepRows
from core.htmpc.ocp_qp import NQ, LevelArrays, QPLayout, StructuredQP
from core.htmpc.task_costs import Linearisation
from core.params import HTMPCParams


@dataclass(frozen=True)
class LexBound:
    """An earlier level's task with its optimum e* (nodes 1..N) for constraint (7c)."""

    lin: Linearisation
    e_star: np.ndarray


def task_cost(arrays: LevelArrays, qp: StructuredQP, lin: Linearisation, q_bar: np.ndarray,
              params: HTMPCParams) -> None:
    """Add dt·½‖e0 + J(q − q̄)‖²_W and the ė part of J_aux, nodes 1..N (in place)."""
    dt, L = params.dt_s, qp.layout
    J, e0 = lin.J[1:], lin.e0[1:]
    JtW = np.swapaxes(J, 1, 2) * lin.weights
    JtWJ = JtW @ J  # (N, 9, 9)
    arrays.h[qp.H_qq[1:]] += dt * JtWJ
    arrays.h[qp.H_vv[1:]] += dt * params.Q_edot * JtWJ
    lin_term = dt * np.einsum("kjm,km->kj", JtW, e0 - np.einsum("kmj,kj->km", J, q_bar[1:]))
    arrays.g[L.idx_q[1:]] += lin_term


def base_arrays(qp: StructuredQP, params: HTMPCParams, q_bar: np.ndarray, rows: CollisionRows | None,
                damping: float | None = None, step: StepRows | None = None) -> LevelArrays:
    """Everything but the task costs and (7c): regularisation, slack costs, dynamics and collision rows (at
    nodes 1..N−1, and `step` in the first interval's acceleration). `damping` is λ of ½ λ ‖q − q̄‖² (default
    `params.sqp_damping`). The parts that do not change between steps are built once per parameter set and λ
    (`_base_template`, kept by the QP) and copied."""
    L = qp.layout
    lam = params.sqp_damping if damping is None else damping
    t = qp.level_templates.get((params, lam))
    if t is None:
        t = qp.level_templates[(params, lam)] = _base_template(qp, params, lam)
    h, g, a, lba, uba = t.h.copy(), t.g.copy(), t.a.copy(), t.lba.copy(), t.uba.copy()
    g[L.idx_q] -= lam * q_bar
    if step is not None:
        a[qp.A_step_a] = step.a_a
        lba[qp.row_step] = step.lb
    if rows is not None:
        a[qp.A_col_q] = rows.a_q[: L.N - 1]
        a[qp.A_col_v] = rows.a_v[: L.N - 1]
        lba[qp.row_col] = rows.lb[: L.N - 1]
    return LevelArrays(h, g, a, lba, uba)


def _base_template(qp: StructuredQP, params: HTMPCParams, lam: float) -> LevelArrays:
    """The constant part of `base_arrays` for one layout, parameter set and damping λ: H of the damping, J_aux
    and the slacks, the slacks' linear cost, the dynamics, the slacks' columns, one-sided collision rows (no
    row without a map). Read-only; `base_arrays` copies it."""
    dt, L = params.dt_s, qp.layout
    h = np.zeros(qp.H_sp.nnz())
    eye = np.eye(NQ)
    h[qp.H_qq] += lam * eye  # ½ λ ‖q − q̄‖²: Levenberg-Marquardt damping, also keeps H > 0
    h[qp.H_vv[1:]] += dt * params.Q_x * eye
    h[qp.H_aa] += dt * params.Q_u
    h[qp.H_ss] += 2.0 * params.slack_quadratic
    g = np.zeros(L.nv)
    g[L.idx_s] += params.slack_linear
    a = qp.A_dynamics_nz.copy()
    a[qp.A_col_s] = 1.0
    a[qp.A_step_s] = 1.0
    lba, uba = np.zeros(L.na), np.zeros(L.na)
    uba[qp.row_col] = uba[qp.row_step] = np.inf
    lba[qp.row_col] = lba[qp.row_step] = -np.inf
    a[qp.A_speed_v] = speed_directions(L.n_speed)
    lba[qp.row_speed], uba[qp.row_speed] = -np.inf, np.inf  # free until `set_speed_rows` bounds them
    for arr in (h, g, a, lba, uba):
        arr.flags.writeable = False
    return LevelArrays(h, g, a, lba, uba)


def speed_directions(n: int) -> np.ndarray:
    """(n, 2) unit directions θ = iπ/n of the planar speed rows."""
    theta = np.pi * np.arange(n) / n
    return np.column_stack([np.cos(theta), np.sin(theta)])


def set_speed_rows(arrays: LevelArrays, qp: StructuredQP, x0: np.ndarray, planar_speed: float) -> None:
    """Bound the base's planar speed rows: |(vx, vy) · (cos θ, sin θ)| ≤ planar_speed · cos(π / 2n) at nodes 1..N,
    a polygon with n direction pairs whose corners lie on the circle of the limit; at node 1 widened to the
    measured velocity's own projections, so that v_1 = v_0 stays feasible (as `variable_bounds` does)."""
    L = qp.layout
    if L.n_speed == 0:
        return
    n = speed_directions(L.n_speed)
    face = planar_speed * np.cos(np.pi / (2 * L.n_speed))
    bound = np.full((L.N, L.n_speed), face)
    bound[0] = np.maximum(face, np.abs(n @ x0[NQ:NQ + 2]) + 1e-6)
    arrays.lba[qp.row_speed], arrays.uba[qp.row_speed] = -bound, bound


def lex_tolerances(params: HTMPCParams) -> np.ndarray:
    """tol_k of (7c) for nodes 1..N, shape (N, 1): `lex_tolerance_first_node` at node 1, the one the robot
    executes before the next step, and `lex_tolerance` on the rest of the plan, which is re-planned anyway.

    A tolerance at node 1 leaks in closed loop: level 2 keeps level 1's error at |e_1*| + tol where level 1
    alone would have moved on, the next step starts from there, and the error settles where level 1's own
    one-node decrease equals tol: tol / (1 − ρ), with ρ the contraction of level 1's error per step
    (docs/decisions.md, "A near-zero (7c) tolerance on the executed node")."""
    tol = np.full((params.N, 1), params.lex_tolerance)
    tol[0] = params.lex_tolerance_first_node
    return tol


def lex_limits(e_star: np.ndarray, tolerance: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi) of (7c) on an earlier task's error e: −(|e*| + tol) ≤ e ≤ |e*| + tol."""
    bound = np.abs(e_star) + tolerance
    return -bound, bound


def add_lex_rows(arrays: LevelArrays, qp: StructuredQP, bounds: list[LexBound], q_bar: np.ndarray,
                 tolerance: np.ndarray | float) -> None:
    """(7c): lo ≤ e0 + J (q − q̄) ≤ hi (`lex_limits`) for every earlier task, nodes 1..N; `tolerance` is
    a scalar or per node (N, 1) (`lex_tolerances`)."""
    if not bounds:
        return
    J = np.concatenate([b.lin.J[1:] for b in bounds], axis=1)  # (N, n_lex, 9)
    e0 = np.concatenate([b.lin.e0[1:] for b in bounds], axis=1)
    lo, hi = lex_limits(np.concatenate([b.e_star for b in bounds], axis=1), tolerance)
    offset = e0 - np.einsum("kmj,kj->km", J, q_bar[1:])
    arrays.a[qp.A_lex_q] = J
    arrays.lba[qp.row_lex] = lo - offset
    arrays.uba[qp.row_lex] = hi - offset


def linearised_errors(lin: Linearisation, q: np.ndarray, q_bar: np.ndarray) -> np.ndarray:
    """e0 + J (q − q̄) at nodes 1..N for a solution q (N+1, 9)."""
    dq = q[1:] - q_bar[1:]
    return lin.e0[1:] + np.einsum("kmj,kj->km", lin.J[1:], dq)


def variable_bounds(layout: QPLayout, x0: np.ndarray, q_min: np.ndarray, q_max: np.ndarray, v_max: np.ndarray,
                    a_max: np.ndarray, dt: float, q_bar: np.ndarray | None = None,
                    trust: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """x_0 fixed; q within limits and within the trust region `trust` around q̄; |v| ≤ v_max (widened at
    node 1 if the robot moves faster now, so the problem stays feasible); |a| ≤ a_max; slacks ≥ 0."""
    L = layout
    lbx = np.empty(L.nv)
    ubx = np.empty(L.nv)
    if trust is not None and q_bar is not None:
        lbx[L.idx_q] = np.maximum(q_min, np.minimum(q_bar - trust, q_max))
        ubx[L.idx_q] = np.minimum(q_max, np.maximum(q_bar + trust, q_min))
    else:
        lbx[L.idx_q], ubx[L.idx_q] = q_min, q_max
    lbx[L.idx_v], ubx[L.idx_v] = -v_max, v_max
    if L.N >= 1:
        v1 = np.maximum(v_max, np.abs(x0[NQ:]) - a_max * dt + 1e-6)
        lbx[L.idx_v[1]], ubx[L.idx_v[1]] = -v1, v1
    lbx[L.idx_a], ubx[L.idx_a] = -a_max, a_max
    lbx[L.idx_s], ubx[L.idx_s] = 0.0, np.inf
    lbx[L.idx_q[0]] = ubx[L.idx_q[0]] = x0[:NQ]
    lbx[L.idx_v[0]] = ubx[L.idx_v[0]] = x0[NQ:]
    return lbx, ubx
