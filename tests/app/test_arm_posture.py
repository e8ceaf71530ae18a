"""The arm keeps its configuration over a lap of the aisle (MuJoCo, HTMPC, ground-truth map): while the base drives,
the arm holds its ready joints, the pan turned to look ahead (`tasks/ready_hand.py`). With the hand's ready pose held
in the world on the reference base instead, the same lap took the elbow and wrist 1 to their limits (π, 2π) before
the second pick."""

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from core.robot.model import READY_Q
from core.scene import aisle_scene
from tasks import BaseSubtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR, load_sequence


@pytest.mark.slow
def test_over_a_lap_the_arm_stays_off_its_limits_and_drives_in_its_ready_pose():
    laps = load_sequence(EXAMPLES_DIR / "aisle_laps.yaml")
    lap = TaskSequence(name="one lap", subtasks=laps.subtasks[:5])
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=aisle_scene(), sequence=lap)
    ends: list[np.ndarray] = []
    index = 0

    def at_control(rt: Runtime) -> None:
        nonlocal index
        if rt.sequencer.index != index:  # a subtask just ended: where the arm is when a drive ends
            if isinstance(lap.subtasks[index], BaseSubtask):
                ends.append(rt.state.q[3:].copy())
            index = rt.sequencer.index

    rt.run_lockstep(150.0, on_control=at_control)
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    q = np.array(rt.log.q)[:, 3:]
    lim = rt.robot.limits
    room = np.minimum(q - lim.q_min[3:], lim.q_max[3:] - q).min(axis=0)
    assert np.all(room > 0.5), f"rad left to each arm joint's limits: {np.round(room, 2)}"
    assert len(ends) >= 2
    for q_end in ends:  # the lift, elbow and wrists back at ready; the pan turned at most to look ahead
        assert np.abs(q_end[1:] - READY_Q[4:]).max() < 0.3, np.round(q_end, 2)
        assert abs(q_end[0] - READY_Q[3]) <= np.radians(rt.sequencer.params.lookahead_turn_max_deg) + 0.05
