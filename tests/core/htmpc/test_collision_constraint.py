"""Eq. (10) rows against a hand-computed case: one sphere, a wall at x = 2, the EDF exact."""

import numpy as np
import pytest

from core.htmpc.collision_constraint import CollisionConstraint
from core.htmpc.horizon_kinematics import HorizonKinematics


class WallField:
    """Signed distance to the half-space x ≥ 2 (a wall), with its exact gradient."""

    def distance(self, p):
        return 2.0 - np.asarray(p)[..., 0]

    def gradient(self, p):
        g = np.zeros(np.shape(p))
        g[..., 0] = -1.0
        return g


def one_sphere_kin(x_positions):
    K = len(x_positions)
    P = np.zeros((K, 1, 3))
    P[:, 0, 0] = x_positions
    JP = np.zeros((K, 1, 3, 9))
    JP[:, 0, 0, 0] = 1.0  # the sphere moves with the base x
    return HorizonKinematics(np.zeros((K, 3)), np.tile(np.eye(3), (K, 1, 1)), np.zeros((K, 3, 9)),
                             np.zeros((K, 3, 9)), P, JP)


def test_barrier_value():
    c = CollisionConstraint(np.array([0.5]), delta_safe_m=0.25, gamma=1.0)
    h = c.barrier(WallField(), np.array([[0.5, 0.0, 0.3]]))
    assert h[0] == pytest.approx(2.0 - 0.5 - 0.5 - 0.25)


def test_cbf_row_hand_computed():
    c = CollisionConstraint(np.array([0.5]), delta_safe_m=0.25, gamma=2.0, kind="cbf")
    q_bar = np.zeros((3, 9))
    q_bar[:, 0] = [0.0, 0.5, 1.0]
    rows = c.rows(q_bar, one_sphere_kin(q_bar[:, 0]), WallField())
    # node 1: h̄ = 2 − 0.5 − 0.75 = 0.75, g = −1 on base x; row: g v + γ g q ≥ γ (g q̄ − h̄)
    assert rows.h[0, 0] == pytest.approx(0.75)
    assert rows.a_v[0, 0, 0] == pytest.approx(-1.0)
    assert rows.a_q[0, 0, 0] == pytest.approx(-2.0)
    assert rows.lb[0, 0] == pytest.approx(2.0 * (-0.5 - 0.75))
    # at q = q̄ the row reads −v ≥ −γ h̄: approaching at speed v ≤ γ h̄ is allowed
    v_allowed = 2.0 * 0.75
    assert rows.a_v[0, 0, 0] * v_allowed + rows.a_q[0, 0, 0] * 0.5 >= rows.lb[0, 0] - 1e-12
    assert rows.a_v[0, 0, 0] * (v_allowed + 0.01) + rows.a_q[0, 0, 0] * 0.5 < rows.lb[0, 0]


def test_edf_row_hand_computed():
    c = CollisionConstraint(np.array([0.5]), delta_safe_m=0.25, gamma=2.0, kind="edf")
    q_bar = np.zeros((2, 9))
    q_bar[1, 0] = 0.5
    rows = c.rows(q_bar, one_sphere_kin(q_bar[:, 0]), WallField())
    # h ≈ h̄ + g (x − x̄) ≥ 0  ⇔  −x ≥ −(x̄ + h̄) = −1.25: the base may go up to x = 1.25
    assert np.all(rows.a_v == 0.0)
    assert rows.a_q[0, 0, 0] == pytest.approx(-1.0)
    assert rows.lb[0, 0] == pytest.approx(-1.25)


def test_unknown_kind_rejected():
    with pytest.raises(ValueError, match="cbf"):
        CollisionConstraint(np.array([0.5]), 0.25, 1.0, kind="potential")


def turning_sphere_kin(theta: float, omega: float):
    """One sphere on a 1 m arm turned by the yaw joint: P = (cos θ, sin θ, 0), at nodes 0 and 1."""
    P = np.zeros((2, 1, 3))
    P[:, 0, :2] = np.cos(theta), np.sin(theta)
    JP = np.zeros((2, 1, 3, 9))
    JP[:, 0, :2, 2] = -np.sin(theta), np.cos(theta)
    dvel = np.zeros((2, 1, 3, 9))  # ∂(J_P v̄)/∂q = v̄_θ ∂(−sin θ, cos θ)/∂θ
    dvel[:, 0, :2, 2] = -omega * np.cos(theta), -omega * np.sin(theta)
    return HorizonKinematics(np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)), np.zeros((2, 3, 9)),
                             np.zeros((2, 3, 9)), P, JP, dvel)


def test_cbf_row_with_a_turning_sphere_hand_computed():
    """θ̄ = π/6, v̄_θ = 2 rad/s, γ = 1.5, wall at x = 2: h̄ = 2 − cos θ̄ − 0.75, g = sin θ̄, c = cos θ̄ · v̄_θ."""
    theta, omega, gamma = np.pi / 6, 2.0, 1.5
    c = CollisionConstraint(np.array([0.5]), delta_safe_m=0.25, gamma=gamma, kind="cbf")
    q_bar = np.zeros((2, 9))
    q_bar[:, 2] = theta
    rows = c.rows(q_bar, turning_sphere_kin(theta, omega), WallField())
    h_bar = 2.0 - np.cos(theta) - 0.75
    g, dv = np.sin(theta), np.cos(theta) * omega
    assert rows.h[0, 0] == pytest.approx(h_bar)
    assert rows.a_v[0, 0, 2] == pytest.approx(g)
    assert rows.a_q[0, 0, 2] == pytest.approx(gamma * g + dv)
    assert rows.lb[0, 0] == pytest.approx((gamma * g + dv) * theta - gamma * h_bar)
    # near (θ̄, v̄) the row is the first-order model of the exact dh/dt + γ h = sin θ v + γ (1.25 − cos θ)
    th, v = theta + 1e-3, omega + 1e-3
    exact = np.sin(th) * v + gamma * (1.25 - np.cos(th))
    model = rows.a_v[0, 0, 2] * v + rows.a_q[0, 0, 2] * th - rows.lb[0, 0]
    assert model == pytest.approx(exact, abs=1e-5)
