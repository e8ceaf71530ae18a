"""A base goal inside a box's clearance in a real closed loop: the planner moves it, the run completes there,
and the studio names the box ("goal moved 0.11 m to clear box_b")."""

from dataclasses import replace

import numpy as np
import pytest
import viser

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from app.ui.progress_panel import ProgressPanel
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence, Tolerance
from tests.app.conftest import free_port


@pytest.mark.slow
def test_moved_goal_completes_and_the_operator_is_told_which_box():
    # box_b's near face is at y = 0.8: a goal at y = 0.1 is 0.7 m from it, inside the base's 0.8 m
    scene = Scene((Box("box_b", (3.0, 1.1, 0.3)), Box("far", (0.0, 4.0, 0.3))), robot_start=(0.0, 0.0, 0.0))
    seq = TaskSequence(subtasks=[BaseSubtask(name="next to box_b", target=BasePose(x=3.0, y=0.1), timeout_s=40.0,
                                             tolerance=Tolerance(position_m=0.05))])
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=scene, sequence=seq)
    shifts = []
    rt.run_lockstep(45.0, on_control=lambda r: shifts.append(r.sequencer.progress[0].goal_shift))
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    shift = next(s for s in shifts if s is not None)
    assert 0.05 < shift.distance_m < 0.3 and shift.driven[1] < 0.1
    assert np.hypot(*(rt.state.q[:2] - shift.driven)) <= 0.05 + 1e-6  # completed where it was sent

    server = viser.ViserServer(port=free_port())
    try:
        snap = rt.snapshot()
        snap = replace(snap, progress=(replace(snap.progress[0], goal_shift=shift),))
        assert f"goal moved {shift.distance_m:.2f} m to clear box_b" in ProgressPanel(server)._list(snap)
    finally:
        server.stop()
