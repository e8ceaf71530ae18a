"""A base goal inside a closed pen of boxes in a real closed loop (MuJoCo, ground-truth map, HTMPC): the subtask
says "no path to the goal" within a control period, the robot holds, and Skip goes on with the next subtask. A gap
the planner passes but the robot's margin does not: the subtask says "blocked" with the nearest obstacle."""

from dataclasses import replace

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from core.params import HTMPCParams
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.sequencer import Outcome


def pen_scene(centre=(4.0, 0.0)) -> Scene:
    """A closed ring of 0.6 m boxes, 3.6 m across, around `centre`; the robot starts at the origin."""
    cx, cy = centre
    boxes = []
    for k, d in enumerate(np.arange(-1.8, 1.81, 0.6)):
        boxes += [Box(f"pen_s{k}", (cx + d, cy - 1.8, 0.3)), Box(f"pen_n{k}", (cx + d, cy + 1.8, 0.3)),
                  Box(f"pen_w{k}", (cx - 1.8, cy + d, 0.3)), Box(f"pen_e{k}", (cx + 1.8, cy + d, 0.3))]
    unique = {b.position: b for b in boxes}  # corners appear twice
    return Scene(tuple(unique.values()), robot_start=(0.0, 0.0, 0.0))


PEN_SEQUENCE = TaskSequence(name="into the pen", subtasks=[
    BaseSubtask(name="into the pen", target=BasePose(x=4.0, y=0.0), timeout_s=60.0),
    BaseSubtask(name="aside", target=BasePose(x=0.0, y=-0.5), timeout_s=30.0)])


@pytest.mark.slow
def test_no_path_is_said_within_a_control_period_the_robot_holds_and_skip_goes_on():
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=pen_scene(), sequence=PEN_SEQUENCE)
    period = 1.0 / rt.controller.params.control_rate_hz
    rt.run_lockstep(period)
    p = rt.sequencer.progress[0]
    assert p.no_path and p.message.startswith("no path to the goal (4.00, 0.00)"), p.message
    assert "no path to the goal" in rt.status_line()
    rt.run_lockstep(3.0)
    assert rt.run_state == RunState.RUNNING
    assert np.hypot(*rt.state.q[:2]) < 0.05  # held where it stood
    rt.skip()
    assert rt.sequencer.progress[0].outcome == Outcome.SKIPPED
    rt.run_lockstep(30.0)
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    assert "1 skipped" in rt.status_line()
    with pytest.raises(ValueError, match="no active subtask"):
        rt.skip()


GAP_M = 1.62
"""A gap in a wall across the whole planning grid: wider than the planner's narrow-passage clearance needs (2 ×
0.65 m), narrower than the base's width plus delta_safe on both sides (2 × (0.395 + 0.45) m)."""
WIDE_MARGIN = replace(HTMPCParams(), delta_safe_m=0.45)


def wall_with_a_gap() -> Scene:
    """0.6 m boxes at x = 2 from the gap's edges to beyond ±8 m (no way round within the planner's grid)."""
    half = GAP_M / 2 + 0.3
    ys = [half + 0.6 * k for k in range(13)]
    return Scene(tuple(Box(f"wall_{i}", (2.0, side * y, 0.3))
                       for i, (side, y) in enumerate((side, y) for side in (1, -1) for y in ys)),
                 robot_start=(0.0, 0.0, 0.0))


THROUGH_THE_GAP = TaskSequence(name="through the gap", subtasks=[
    BaseSubtask(name="through", target=BasePose(x=4.0, y=0.0), timeout_s=90.0)])


@pytest.mark.slow
def test_a_robot_held_by_its_margin_says_blocked_with_the_nearest_obstacle():
    """The planner passes the gap; the collision constraint holds the base delta_safe from the boxes, so it stops
    before it: after `stall_s` without progress the subtask says so, with the nearest obstacle, and nothing is hit."""
    rt = Runtime(RuntimeConfig(map_kind="ground_truth", htmpc=WIDE_MARGIN), scene=wall_with_a_gap(),
                 sequence=THROUGH_THE_GAP)
    rt.run_lockstep(rt.sequencer.params.stall_s + 12.0)
    p = rt.sequencer.progress[0]
    assert p.blocked is not None and p.message.startswith("blocked: no progress for"), p.message
    assert "nearest obstacle" in p.message and "blocked" in rt.status_line()
    assert rt.run_state == RunState.RUNNING and not rt.world.collisions
    assert rt.state.q[0] < 2.0 - 0.3  # held before the wall

