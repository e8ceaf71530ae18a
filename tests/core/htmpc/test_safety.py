"""Fault injection: a failing QP, a broken map, a NaN state and a time-out all lead to a safe stop;
every command that leaves the controller is finite and within the limits."""

import numpy as np

from core.htmpc import HTMPC
from core.params import HTMPCParams
from core.robot.model import READY_Q
from core.sim.ground_truth import ground_truth_edf
from core.sim.scene import Box, Scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import BaseReference, LocalEDF, PlanStatus, References, RobotState

DRIVE = References(order=("base", "ee"), base=BaseReference(np.array([[4.0, 0.0]]), np.zeros(1)))


def moving_state(robot, speed=0.8) -> RobotState:
    v = np.zeros(9)
    v[0], v[3] = speed, 1.5
    return RobotState(1.0, READY_Q.copy(), v)


def assert_commands_safe(robot, plan) -> None:
    for t in np.linspace(plan.t, plan.t + plan.dt * len(plan.u) + 0.5, 200):
        qdot = plan.velocity_at(t)
        assert np.all(np.isfinite(qdot))
        assert np.all(np.abs(qdot) <= robot.limits.v_max + 1e-9)


def assert_brakes(robot, plan, state) -> None:
    assert np.all(np.abs(plan.u) <= robot.limits.a_max + 1e-9)
    np.testing.assert_allclose(plan.v[0], state.v)
    assert np.all(plan.v[-1] == 0.0)
    speeds = np.abs(plan.v[:, 0])
    assert np.all(np.diff(speeds) <= 1e-12)  # monotone deceleration


def test_broken_map_makes_the_qp_fail_and_the_robot_brake(robot):
    broken = LocalEDF(origin=np.array([-2.0, -2.0, 0.0]), voxel=0.1, values=np.full((41, 41, 15), np.nan), cutoff=1.8)
    c = HTMPC(robot)
    state = moving_state(robot)
    plan = c.solve(state, DRIVE, broken)
    assert plan.status == PlanStatus.FALLBACK and "braking" in plan.message
    assert_brakes(robot, plan, state)
    assert_commands_safe(robot, plan)


def test_nan_state_stops(robot):
    c = HTMPC(robot)
    q = READY_Q.copy()
    q[4] = np.nan
    plan = c.solve(RobotState(2.0, q, np.full(9, np.nan)), DRIVE, None)
    assert plan.status == PlanStatus.STOPPING and "non-finite" in plan.message
    assert np.all(plan.v == 0.0)
    assert_commands_safe(robot, plan)


def test_timeout_discards_the_solution(robot):
    c = HTMPC(robot, HTMPCParams(solve_timeout_ms=1e-3))
    state = moving_state(robot)
    plan = c.solve(state, DRIVE, None)
    assert plan.status == PlanStatus.FALLBACK and "took" in plan.message
    assert_brakes(robot, plan, state)


def test_solver_failures_in_closed_loop_stop_the_robot(robot):
    """A robot driving at speed whose map turns to NaN comes to rest within the deceleration limits."""
    world = SimWorld(robot, scene=Scene((Box("b", (5.0, 2.0, 0.3)),)))
    world.set_robot(READY_Q)
    sim = SimRobot(world, cameras=())
    c = HTMPC(robot)
    plan = None
    speeds = []
    for k in range(600):
        state = sim.observe().state
        if k % 10 == 0:
            edf = ground_truth_edf(world.obstacles(), state.q[:2])
            if k >= 300:  # the map breaks: NaN everywhere around the robot
                edf = LocalEDF(edf.origin, edf.voxel, np.full_like(edf.values, np.nan), edf.cutoff)
            plan = c.solve(state, DRIVE, edf)
            if k >= 300:
                assert plan.status in (PlanStatus.FALLBACK, PlanStatus.STOPPING)
        qdot = plan.velocity_at(state.t)
        assert np.all(np.isfinite(qdot)) and np.all(np.abs(qdot) <= robot.limits.v_max + 1e-9)
        sim.command(qdot, state.t)
        sim.step(0.01)
        speeds.append(np.hypot(*state.v[:2]))
    assert max(speeds[250:300]) > 0.3  # it was moving when the map broke
    assert speeds[-1] < 0.02  # and it stopped
    assert world.collisions == []
