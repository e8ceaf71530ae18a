"""The structured QP: HPIPM on our stage-wise layout equals a general QP solver on the same data."""

import casadi as ca
import numpy as np
import pytest

from core.htmpc.level_problem import base_arrays, task_cost, variable_bounds
from core.htmpc.ocp_qp import QPLayout, StructuredQP
from core.htmpc.task_costs import Linearisation
from core.params import HTMPCParams


def test_hpipm_matches_a_dense_solver_and_respects_the_dynamics(robot):
    params = HTMPCParams(N=6)
    layout = QPLayout(params.N, n_spheres=3, n_lex=2, slack_group=np.array([0, 0, 1]))
    qp = StructuredQP(layout, params.dt_s)
    rng = np.random.default_rng(0)
    q_bar = np.zeros((params.N + 1, 9))
    from core.htmpc.collision_constraint import CollisionRows

    n = params.N
    rows = CollisionRows(a_q=rng.normal(size=(n, 3, 9)), a_v=rng.normal(size=(n, 3, 9)),
                         lb=rng.uniform(-1, 0.5, size=(n, 3)), h=np.zeros((n, 3)))
    from core.htmpc.collision_constraint import StepRows

    step = StepRows(a_a=rng.normal(size=(3, 9)), lb=rng.uniform(-1, 0.5, size=3), h=np.zeros(3))
    arrays = base_arrays(qp, params, q_bar, rows, step=step)
    lin = Linearisation("base", e0=rng.normal(size=(n + 1, 3)), J=np.tile(-np.eye(3, 9), (n + 1, 1, 1)),
                        weights=np.ones(3))
    task_cost(arrays, qp, lin, q_bar, params)
    arrays.lba[qp.row_lex] = -0.5  # a box on the first two q entries via the (7c) rows
    arrays.uba[qp.row_lex] = 0.5
    arrays.a[qp.A_lex_q] = np.tile(np.eye(2, 9), (n, 1, 1))
    x0 = np.concatenate([rng.normal(size=9) * 0.1, np.zeros(9)])
    lim = robot.limits
    lbx, ubx = variable_bounds(layout, x0, lim.q_min, lim.q_max, lim.v_max, lim.a_max, params.dt_s)
    sol = qp.solve(arrays.h, arrays.g, arrays.a, arrays.lba, arrays.uba, lbx, ubx)
    assert sol.success, sol.status
    # qrqp returned infeasible points flagged as success on this problem; OSQP at tight tolerances is reliable
    ref = ca.conic("ref", "osqp", {"h": qp.H_sp, "a": qp.A_sp},
                   {"osqp": {"verbose": False, "eps_abs": 1e-9, "eps_rel": 1e-9, "max_iter": 200000}})
    out = ref(h=ca.DM(qp.H_sp, arrays.h), g=arrays.g, a=ca.DM(qp.A_sp, arrays.a), lba=arrays.lba,
              uba=arrays.uba, lbx=lbx, ubx=ubx)
    H, A = np.array(ca.DM(qp.H_sp, arrays.h)), np.array(ca.DM(qp.A_sp, arrays.a))

    def objective(z):
        return 0.5 * z @ H @ z + arrays.g @ z

    def violation(z):
        Az = A @ z
        return max(np.max(arrays.lba - Az), np.max(Az - arrays.uba), np.max(np.maximum(lbx, -1e8) - z),
                   np.max(z - np.minimum(ubx, 1e8)))

    z_ref = np.asarray(out["x"]).ravel()
    assert violation(sol.z) < 1e-6 and violation(z_ref) < 1e-6
    # the optimum need not be unique; HPIPM stops at residuals of 1e-6 (ocp_qp.HPIPM_OPTIONS)
    # (with residuals of 1e-9 HPIPM reaches OSQP's objective to 1e-10; at 1e-6 the slack rows leave ~4e-4)
    assert objective(sol.z) == pytest.approx(objective(z_ref), rel=1e-3, abs=1e-6)
    q, v, a = layout.states(sol.z)
    dt = params.dt_s
    np.testing.assert_allclose(q[1:], q[:-1] + dt * v[:-1] + 0.5 * dt * dt * a, atol=1e-6)
    np.testing.assert_allclose(v[1:], v[:-1] + dt * a, atol=1e-6)
    assert np.all(np.abs(a) <= lim.a_max + 1e-6)
    assert np.all(np.abs(q[1:, :2]) <= 0.5 + 1e-5)
    # the first interval's rows: a_a · a_0 + s_0 ≥ lb with the slack of each row's group
    s0 = sol.z[layout.s(0)][layout.slack_group]
    assert np.all(step.a_a @ a[0] + s0 >= step.lb - 1e-6)


def test_the_buffered_call_solves_each_new_qp_like_a_fresh_dm_call(robot):
    """The solver runs through a re-bound `Function.buffer()`; without the re-binding every call after the first
    solved stale data. A sequence of different QPs (and a warm start) must give what a plain `DM` call gives."""
    from core.htmpc.collision_constraint import CollisionRows, StepRows

    params = HTMPCParams(N=5)
    n = params.N
    layout = QPLayout(n, n_spheres=3, n_lex=0, slack_group=np.array([0, 0, 1]))
    qp = StructuredQP(layout, params.dt_s)
    lim = robot.limits
    guess = None
    for seed in range(4):
        rng = np.random.default_rng(seed)
        rows = CollisionRows(a_q=rng.normal(size=(n, 3, 9)), a_v=rng.normal(size=(n, 3, 9)),
                             lb=rng.uniform(-1, 0.5, size=(n, 3)), h=np.zeros((n, 3)))
        step = StepRows(a_a=rng.normal(size=(3, 9)), lb=rng.uniform(-1, 0.5, size=3), h=np.zeros(3))
        q_bar = np.tile(rng.normal(size=9) * 0.1, (n + 1, 1))
        arrays = base_arrays(qp, params, q_bar, rows, step=step)
        lin = Linearisation("base", e0=rng.normal(size=(n + 1, 3)), J=np.tile(-np.eye(3, 9), (n + 1, 1, 1)),
                            weights=np.ones(3))
        task_cost(arrays, qp, lin, q_bar, params)
        x0 = np.concatenate([q_bar[0], rng.normal(size=9) * 0.1])
        lbx, ubx = variable_bounds(layout, x0, lim.q_min, lim.q_max, lim.v_max, lim.a_max, params.dt_s)
        sol = qp.solve(arrays.h, arrays.g, arrays.a, arrays.lba, arrays.uba, lbx, ubx, guess)
        args = {"h": ca.DM(qp.H_sp, arrays.h), "g": arrays.g, "a": ca.DM(qp.A_sp, arrays.a), "lba": arrays.lba,
                "uba": arrays.uba, "lbx": lbx, "ubx": ubx}
        if guess is not None:
            args["x0"] = guess
        plain = np.asarray(qp.solver(**args)["x"]).ravel()
        assert sol.success, sol.status
        np.testing.assert_allclose(sol.z, plain, rtol=0, atol=1e-12)
        guess = sol.z
