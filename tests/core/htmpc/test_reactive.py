"""Reactive avoidance near the physical limit (ground-truth EDF, no delay, delta 0, gamma 0.5 as in E3): the
base cruises at 1 m/s along a straight reference and a box appears just before a control step.

At 1 m/s and 2 m/s² the base needs 0.25 m to stop (`bench/experiments/avoidability.py`)."""

import numpy as np
import pytest

from bench.experiments.avoidability import Push, avoidable_by
from core.htmpc import HTMPC
from core.params import HTMPCParams
from core.robot.model import READY_Q
from core.scene import Box, Scene
from core.sim.world import SimWorld
from core.types import BaseReference, EEReference, References
from tests.core.htmpc.closed_loop import run

pytestmark = pytest.mark.slow

SPEED, PUSH_T, SECONDS = 1.0, 1.0, 3.0
E3 = HTMPCParams(gamma=0.5, delta_safe_m=0.0)
HALF_BASE = (0.48, 0.395)


def cruise(robot):
    """Whole-body navigation references: the base along y = 0 at 1 m/s, the hand at its ready offset."""
    ready = robot.ee_pose(READY_Q)
    t_nodes = E3.dt_s * np.arange(E3.N + 1)

    def refs(t: float) -> References:
        x = SPEED * (t + t_nodes)
        hand = np.column_stack([x + ready[0, 3], np.full_like(x, ready[1, 3]), np.full_like(x, ready[2, 3])])
        return References(("base", "ee"), BaseReference(np.column_stack([x, np.zeros_like(x)]), np.zeros_like(x)),
                          EEReference(hand, np.repeat(ready[None, :3, :3], len(x), axis=0)), switched=t == 0.0)

    return refs


def push_run(robot, ahead_m: float, lateral_m: float, bottom_m: float, from_x_m: float):
    """Drive, put a 0.6 m box with its near face `ahead_m` beyond base x + `from_x_m` at PUSH_T; the log."""
    world = SimWorld(robot, scene=Scene((Box("push", (-20.0, 20.0, bottom_m + 0.3)),)))
    v = np.zeros(9)
    v[0] = SPEED
    world.set_robot(READY_Q, v)
    pushed = {}

    def before_control(w, state):
        if not pushed and state.t >= PUSH_T - 1e-9:
            w.move_box("push", (state.q[0] + from_x_m + ahead_m + 0.3, state.q[1] + lateral_m, bottom_m + 0.3))
            pushed["distance"] = w.robot_box_distance()[0]

    log = run(world, HTMPC(robot, E3), cruise(robot), SECONDS, before_control=before_control)
    return world, log, pushed["distance"]


def test_base_brakes_to_a_stop_before_a_box_appearing_inside_twice_its_stopping_distance(robot):
    world, log, distance = push_run(robot, 0.3, 0.0, 0.0, HALF_BASE[0])
    assert distance == pytest.approx(0.3, abs=0.01)
    assert world.collisions == []
    assert abs(log.v[-1][0]) < 0.05  # stopped in front of it


def test_base_sidesteps_a_box_that_braking_alone_cannot_avoid(robot):
    ahead, lateral = 0.22, 0.65  # the box overlaps the base's path by 4.5 cm on the left
    ways = avoidable_by(Push(HALF_BASE[0] + ahead + 0.3, lateral, 0.0, (0.6, 0.6)), HALF_BASE, SPEED, 0.0, 2.0, 1.0)
    assert "brake" not in ways and "right" in ways
    world, log, _ = push_run(robot, ahead, lateral, 0.0, HALF_BASE[0])
    assert world.collisions == []
    assert min(q[1] for q in log.q) < -0.05  # it went round on the right
    assert log.q[-1][0] > 2.0  # and drove on


def test_arm_pulls_the_hand_back_from_a_box_at_hand_height(robot):
    """A box floating at hand height (0.65–1.25 m, above the base body) appears 0.21 m in front of the hand:
    braking alone needs 0.25 m, so the arm must take the hand out of the way."""
    world, log, distance = push_run(robot, 1.0, 0.0, 0.65, 0.0)
    assert distance < 0.25
    assert world.collisions == []
    reach = [robot.ee_pose(q)[0, 3] - q[0] for q in log.q]
    assert reach[int(PUSH_T * 10) - 1] - min(reach) > 0.1  # the hand came back toward the base by > 10 cm
