"""A base goal inside a closed pen of boxes in a real closed loop (MuJoCo, ground-truth map, HTMPC): the subtask
says "no path to the goal" within a control period, the robot holds, and Skip goes on with the next subtask."""

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
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
