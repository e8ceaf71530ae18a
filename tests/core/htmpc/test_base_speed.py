"""The base's speed over the floor stays within its limit whichever way it drives: the QP's planar speed rows
(a 16-gon inside the circle ‖(vx, vy)‖ ≤ 1 m/s; the variable bounds alone are a square whose corners are
√2 m/s), the plan and the commands (`JointLimits.clip_velocity`)."""

import numpy as np
import pytest

from core.htmpc import HTMPC
from core.params import HTMPCParams
from core.types import BaseReference, PlanStatus, References, RobotState
from tests.core.htmpc.conftest import lockstep, ready_state


@pytest.mark.parametrize("heading_deg", [0.0, 30.0, 45.0, 135.0, -60.0])
def test_a_base_goal_far_away_is_approached_at_the_planar_limit_never_over_it(robot, heading_deg):
    c = lockstep(HTMPC(robot, HTMPCParams()))
    direction = np.array([np.cos(np.radians(heading_deg)), np.sin(np.radians(heading_deg))])
    refs = References(order=("base",), base=BaseReference(xy=20.0 * direction[None], yaw=np.zeros(1)), switched=True)
    state, limit = ready_state(), robot.limits.planar_speed
    fastest = 0.0
    for k in range(30):  # 3 s at 10 Hz, the robot following its plan exactly
        plan = c.solve(state, refs, None)
        solved = c.last_step.v  # the QP's own solution, before the plan's clip
        planar = np.hypot(solved[:, 0], solved[:, 1])
        assert planar.max() <= limit + 1e-6, f"step {k}: the QP planned {planar.max():.3f} m/s"
        np.testing.assert_allclose(plan.v[:, :2], solved[:, :2])  # so the plan's clip changed nothing
        fastest = max(fastest, float(planar.max()))
        v = plan.velocity_at(state.t + 0.1)
        state = RobotState(state.t + 0.1, state.q + 0.05 * (plan.velocity_at(state.t) + v), v)
        refs = References(order=("base",), base=refs.base, switched=False)
    assert fastest >= 0.97 * limit  # the polygon's faces lie at cos(π/16) = 98 % of the limit
    v_end = np.hypot(*state.v[:2])
    assert v_end >= 0.95 * limit and float(np.dot(state.v[:2], direction)) >= 0.95 * v_end  # toward the goal


def test_the_qp_widens_its_first_node_to_a_measured_speed_over_the_polygon(robot):
    """A robot measured at 0.995 m/s along an axis (above the 16-gon's face, within the circle) still gets a
    plan, which brings the speed back within the polygon."""
    c = lockstep(HTMPC(robot, HTMPCParams()))
    state = ready_state()
    state = RobotState(0.0, state.q, np.r_[0.995, 0.0, np.zeros(7)])
    refs = References(order=("base",), base=BaseReference(xy=np.array([[20.0, 0.0]]), yaw=np.zeros(1)),
                      switched=True)
    plan = c.solve(state, refs, None)
    assert plan.status == PlanStatus.OK and c.last_step.failed_level is None
    planar = np.hypot(plan.v[:, 0], plan.v[:, 1])
    assert planar.max() <= 0.995 + 1e-6 and planar[2:].max() <= robot.limits.planar_speed * np.cos(np.pi / 16) + 1e-6
