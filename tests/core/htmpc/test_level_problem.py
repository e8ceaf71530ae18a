"""Eqs. (7c) and (8) of the level QP against hand-computed entries."""

import casadi as ca
import numpy as np
import pytest

from core.htmpc.level_problem import LexBound, add_lex_rows, base_arrays, lex_limits, lex_tolerances, task_cost
from core.htmpc.ocp_qp import QPLayout, StructuredQP
from core.htmpc.task_costs import Linearisation
from core.params import HTMPCParams


@pytest.fixture(scope="module")
def qp():
    return StructuredQP(QPLayout(N=3, n_spheres=2, n_lex=1, slack_group=np.array([0, 0])), dt=0.3)


def dense(qp, arrays):
    return np.array(ca.DM(qp.H_sp, arrays.h)), np.array(ca.DM(qp.A_sp, arrays.a))


def test_task_cost_and_aux_terms(qp):
    """Base x task, weight 2, e0 = 1 at q̄ = 0, J = −1: dt·½·2·(1 − x)² and the ė term on v."""
    p = HTMPCParams(N=3, dt_s=0.3, Q_edot=0.5, Q_x=0.1, Q_u=0.2, slack_linear=50.0, slack_quadratic=1.0)
    q_bar = np.zeros((4, 9))
    arrays = base_arrays(qp, p, q_bar, None)
    J = np.zeros((4, 1, 9))
    J[:, 0, 0] = -1.0
    task_cost(arrays, qp, Linearisation("base", np.ones((4, 1)), J, np.array([2.0])), q_bar, p)
    H, _ = dense(qp, arrays)
    L = qp.layout
    k = 2
    x, vx, ax, s = L.q(k).start, L.v(k).start, L.a(k).start, L.s(k).start
    assert H[x, x] == pytest.approx(0.3 * 2.0 + p.sqp_damping)  # dt · w · J² + λ
    assert arrays.g[x] == pytest.approx(0.3 * 2.0 * (-1.0) * 1.0)  # dt · J w e0
    assert H[vx, vx] == pytest.approx(0.3 * (0.5 * 2.0 + 0.1))  # dt (Q_edot w J² + Q_x)
    assert H[ax, ax] == pytest.approx(0.3 * 0.2)  # dt Q_u
    assert H[s, s] == pytest.approx(2.0) and arrays.g[s] == pytest.approx(50.0)  # 50 s + 1 s²
    assert H[L.q(0).start, L.q(0).start] == pytest.approx(p.sqp_damping)  # node 0 carries no task cost


def test_lexicographic_rows_7c(qp):
    """|e0 + J(q − q̄)| ≤ |e*| + tol, with e0 = 0.2, J = −1 on base x, q̄_x = 0.5, e* = −0.05, tol 0.01."""
    p = HTMPCParams(N=3)
    q_bar = np.zeros((4, 9))
    q_bar[:, 0] = 0.5
    arrays = base_arrays(qp, p, q_bar, None)
    J = np.zeros((4, 1, 9))
    J[:, 0, 0] = -1.0
    lin = Linearisation("ee", np.full((4, 1), 0.2), J, np.ones(1))
    add_lex_rows(arrays, qp, [LexBound(lin, np.full((3, 1), -0.05))], q_bar, tolerance=0.01)
    _, A = dense(qp, arrays)
    for k in (1, 2, 3):
        row = qp.lex_rows(k)[0]
        assert A[row, qp.layout.q(k).start] == -1.0
        # −0.06 ≤ 0.2 − (x − 0.5) ≤ 0.06   ⇔   −x ∈ [−0.76, −0.64]
        assert arrays.lba[row] == pytest.approx(-0.06 - 0.7)
        assert arrays.uba[row] == pytest.approx(0.06 - 0.7)


def test_lex_tolerance_is_tight_on_the_executed_node():
    p = HTMPCParams(N=4, lex_tolerance=0.01, lex_tolerance_first_node=1e-4)
    np.testing.assert_allclose(lex_tolerances(p)[:, 0], [1e-4, 0.01, 0.01, 0.01])
    lo, hi = lex_limits(np.array([[0.2, -0.3, 0.0]]), lex_tolerances(p)[:1])
    np.testing.assert_allclose(lo, [[-0.2001, -0.3001, -1e-4]])
    np.testing.assert_allclose(hi, [[0.2001, 0.3001, 1e-4]])
