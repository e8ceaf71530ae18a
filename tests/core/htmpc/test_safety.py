"""Fault injection: a failing QP, a broken map, a NaN state and a time-out all lead to a safe stop;
every command that leaves the controller is finite and within the limits."""

import numpy as np
import pytest

from core.htmpc import HTMPC
from core.htmpc.safety import brake_along
from core.params import HTMPCParams, SensorParams
from core.robot.model import READY_Q
from core.scene import Box, Scene
from core.sim.ground_truth import ground_truth_edf
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import BaseReference, LocalEDF, Plan, PlanReason, PlanStatus, References, RobotState
from tests.core.htmpc.conftest import lockstep

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
    c = lockstep(HTMPC(robot))
    state = moving_state(robot)
    plan = c.solve(state, DRIVE, broken)
    assert plan.status == PlanStatus.FALLBACK and "braking" in plan.message and plan.reason == PlanReason.QP_FAILED
    assert_brakes(robot, plan, state)
    assert_commands_safe(robot, plan)


class RaisingMap:
    """A map whose queries raise: a fault of any type inside the solve."""

    def __init__(self, error: Exception) -> None:
        self.error = error

    def distance(self, p):
        raise self.error

    def gradient(self, p):
        raise self.error


@pytest.mark.parametrize("error", [RuntimeError("driver died"), KeyError("voxel"), AssertionError("broken")])
def test_any_exception_in_the_solve_brakes(robot, error):
    c = lockstep(HTMPC(robot))
    state = moving_state(robot)
    plan = c.solve(state, DRIVE, RaisingMap(error))
    assert plan.status == PlanStatus.FALLBACK and type(error).__name__ in plan.message
    assert plan.reason == PlanReason.CONTROLLER_ERROR
    assert_brakes(robot, plan, state)
    assert_commands_safe(robot, plan)


def test_nan_state_stops(robot):
    c = lockstep(HTMPC(robot))
    q = READY_Q.copy()
    q[4] = np.nan
    plan = c.solve(RobotState(2.0, q, np.full(9, np.nan)), DRIVE, None)
    assert plan.status == PlanStatus.STOPPING and "non-finite" in plan.message
    assert plan.reason == PlanReason.NON_FINITE_STATE
    assert np.all(plan.v == 0.0)
    assert_commands_safe(robot, plan)


def test_timeout_discards_the_solution(robot):
    c = HTMPC(robot, HTMPCParams(solve_timeout_ms=1e-3))
    state = moving_state(robot)
    plan = c.solve(state, DRIVE, None)
    assert plan.status == PlanStatus.FALLBACK and "took" in plan.message
    assert plan.reason == PlanReason.SOLVE_TIMEOUT
    assert_brakes(robot, plan, state)


def test_solver_failures_in_closed_loop_stop_the_robot(robot):
    """A robot driving at speed whose map turns to NaN comes to rest within the deceleration limits."""
    world = SimWorld(robot, scene=Scene((Box("b", (5.0, 2.0, 0.3)),)))
    world.set_robot(READY_Q)
    sim = SimRobot(world, cameras=(), sensor=SensorParams.ideal())
    c = lockstep(HTMPC(robot))
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


def constant_turn_plan(robot, t0=1.0, dt=0.3, N=10) -> Plan:
    """A plan driving the base at 0.8 m/s along x while turning its velocity toward y at 0.5 m/s²."""
    a = np.zeros((N, 9))
    a[:, 1] = 0.5
    v = np.zeros((N + 1, 9))
    v[:, 0] = 0.8
    v[:, 1] = 0.5 * dt * np.arange(N + 1)
    q = np.tile(READY_Q, (N + 1, 1))
    q[:, 0] = 0.8 * dt * np.arange(N + 1)
    q[:, 1] = 0.25 * (dt * np.arange(N + 1)) ** 2
    return Plan(t=t0, dt=dt, q=q, v=v, u=a, base_path=q[:, :3].copy(), ee_path=np.zeros((N + 1, 3)),
                task_errors=(0.0,), solve_ms=(1.0,), status=PlanStatus.OK)


def test_brake_along_keeps_the_previous_path_and_stops_within_limits(robot):
    prev = constant_turn_plan(robot)
    plan = brake_along(prev, 1.3, robot.limits, N=10, dt=0.3, status=PlanStatus.FALLBACK, message="test")
    # hand computation: at s0 = 0.3 the base moves at (0.8, 0.15); braking x alone takes 0.8/2 = 0.4 s,
    # but the turn's own 0.5 m/s² adds to y, so T_b is the first of 0.4·1.25^i that keeps |ÿ| ≤ 2: with
    # T_b = 0.5, ÿ(0) = 0.5 − 0.15/0.5 = 0.2 and ẍ = −1.6, both fine; with T_b = 0.4, ẍ = −2.0 is at the limit
    assert plan.extras["braking_time_s"] == pytest.approx(0.5)
    # s(t) = s0 + t − t²/(2 T_b): at t = 0.3, s = 0.3 + 0.3 − 0.09 = 0.51 and ṡ = 1 − 0.3/0.5 = 0.4
    np.testing.assert_allclose(plan.v[1, :2], 0.4 * np.array([0.8, 0.5 * 0.51]))
    np.testing.assert_allclose(plan.q[1, :2], [0.8 * 0.51, 0.25 * 0.51**2])  # on the previous path
    assert np.all(plan.v[2:] == 0.0)  # stopped after T_b
    assert np.all(np.abs(plan.u) <= robot.limits.a_max)
    assert_commands_safe(robot, plan)
    # a failure while braking keeps braking: the same plan, with the new reason
    again = brake_along(plan, 1.4, robot.limits, N=10, dt=0.3, status=PlanStatus.FALLBACK, message="again")
    assert again.v is plan.v and again.message == "again"


def test_qp_failure_in_closed_loop_brakes_along_the_previous_plan(robot):
    """A real HPIPM failure: from 3 s on the arm's encoder reads a joint 6 rad past its limit, so no
    trajectory within the joint bounds starts there (the QP is infeasible). The robot stops along its plan."""
    world = SimWorld(robot, scene=Scene())
    world.set_robot(READY_Q)
    sim = SimRobot(world, cameras=(), sensor=SensorParams.ideal())
    c = lockstep(HTMPC(robot))
    plan, plans, commands, base_xy = None, [], [], []
    for k in range(500):
        state = sim.observe().state
        if k % 10 == 0:
            if k >= 300:
                q = state.q.copy()
                q[4] = robot.limits.q_max[4] + 6.0
                state = RobotState(state.t, q, state.v)
            plan = c.solve(state, DRIVE, None)
            plans.append(plan)
            if k >= 300:
                assert plan.status == PlanStatus.FALLBACK and "QP failed" in plan.message, plan.message
                assert plan.reason == PlanReason.QP_FAILED
        qdot = plan.velocity_at(sim.observe().state.t)
        commands.append(qdot)
        assert np.all(np.isfinite(qdot)) and np.all(np.abs(qdot) <= robot.limits.v_max + 1e-9)
        sim.command(qdot, sim.observe().state.t)
        sim.step(0.01)
        base_xy.append(world.state().q[:2].copy())
    before = plans[29]
    assert np.hypot(*before.v[0, :2]) > 0.3  # it was driving when the QP started to fail
    braking = np.array(commands[300:])
    assert np.all(np.abs(np.diff(braking, axis=0)) / 0.01 <= robot.limits.a_max + 1e-6)  # within a_max
    assert np.all(braking[-100:] == 0.0)
    assert np.hypot(*world.state().v[:2]) < 0.02
    # the robot stopped on the path the last good plan had planned
    path = before.q[:, :2]
    stop = base_xy[-1]
    seg = np.diff(path, axis=0)
    w = np.clip(np.einsum("ij,ij->i", stop - path[:-1], seg) / np.maximum(np.einsum("ij,ij->i", seg, seg), 1e-12), 0, 1)
    assert np.min(np.linalg.norm(path[:-1] + w[:, None] * seg - stop, axis=1)) < 0.05


def test_nan_state_after_a_plan_stops_along_that_plan(robot):
    c = lockstep(HTMPC(robot))
    state = moving_state(robot)
    good = c.solve(state, DRIVE, None)
    assert good.status in (PlanStatus.OK, PlanStatus.SLACK)
    q = np.full(9, np.nan)
    plan = c.solve(RobotState(state.t + 0.1, q, q), DRIVE, None)
    assert plan.status == PlanStatus.STOPPING and "previous plan" in plan.message
    np.testing.assert_allclose(plan.v[0], good.velocity_at(state.t + 0.1))  # no jump in the command
    assert np.all(plan.v[-1] == 0.0) and np.all(np.abs(plan.u) <= robot.limits.a_max)
    assert_commands_safe(robot, plan)
