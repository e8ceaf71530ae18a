"""`Plan.velocity_at`: how the 100 Hz command stream is read from a 10 Hz plan (docs/method.md, "References
for the tasks, and commands")."""

from __future__ import annotations

import numpy as np

from core.types import Plan, PlanStatus


def _plan(t0: float = 2.0, dt: float = 0.3) -> Plan:
    v = np.zeros((4, 9))
    u = np.zeros((3, 9))
    v[:, 0] = [0.1, 0.4, 0.7, 0.7]  # base x accelerates at 1 m/s² for two intervals, then cruises
    u[:, 0] = [1.0, 1.0, 0.0]
    q = np.zeros((4, 9))
    return Plan(t=t0, dt=dt, q=q, v=v, u=u, base_path=q[:, :2], ee_path=q[:, :3], task_errors=(), solve_ms=(),
                status=PlanStatus.OK)


def test_velocity_is_v_k_plus_u_k_times_the_time_into_interval_k() -> None:
    plan = _plan()
    for t, expected in ((2.0, 0.1), (2.01, 0.11), (2.15, 0.25), (2.45, 0.55), (2.75, 0.7)):
        np.testing.assert_allclose(plan.velocity_at(t)[0], expected, atol=1e-12)
        assert np.all(plan.velocity_at(t)[1:] == 0.0)


def test_before_the_plan_its_first_velocity_and_after_the_horizon_zero() -> None:
    plan = _plan()
    np.testing.assert_array_equal(plan.velocity_at(1.9), plan.v[0])
    np.testing.assert_array_equal(plan.velocity_at(2.0 + 3 * 0.3 + 1e-6), np.zeros(9))
