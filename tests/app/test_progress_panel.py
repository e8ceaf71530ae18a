"""The status the progress panel writes, from made-up snapshots: no '0 s' artefacts, ETAs within the timeout,
'ready' for a sequence authored after a finished run, edits during a run (paused or stopped too) waiting for the next
run."""

import re
from dataclasses import replace

import numpy as np
import pytest
import viser

from app.runtime.snapshot import RunState, Snapshot
from app.ui.progress_panel import ProgressPanel, duration
from core.types import RobotState
from tasks.sequencer import Blocked, Outcome, SubtaskProgress
from tests.app.conftest import free_port


def snap(t: float, run_state: RunState, progress, version: int = 0) -> Snapshot:
    return Snapshot(seq=0, wall_time=0.0, state=RobotState(t, np.zeros(9), np.zeros(9)), run_state=run_state,
                    progress=tuple(progress), sequence_version=version)


def pending(n: int, timeout_s: float = 30.0):
    return [SubtaskProgress(i, f"s{i + 1}", "base", timeout_s=timeout_s) for i in range(n)]


@pytest.fixture
def panel():
    server = viser.ViserServer(port=free_port())
    yield ProgressPanel(server)
    server.stop()


def seconds_in(text: str) -> list[float]:
    return [float(x) for x in re.findall(r"(\d+(?:\.\d+)?) s\b", text)]


def test_durations_never_read_zero_for_a_short_run():
    assert duration(0.4) == "0.4 s" and duration(9.96) == "10.0 s" and duration(45.2) == "45 s"
    assert duration(125) == "2 min 05 s"


def test_a_sequence_authored_after_a_finished_run_reads_ready(panel):
    panel.update(snap(20.0, RunState.FINISHED, pending(5)))
    assert "**ready**" in panel.status.content and "finished" not in panel.status.content
    assert panel.time_left.content == "5 subtasks, at most 2 min 30 s by their timeouts"
    panel.update(snap(20.0, RunState.FINISHED, [replace(p, outcome=Outcome.DONE, elapsed_s=0.3) for p in pending(1)]))
    assert panel.time_left.content == "finished after 0.3 s"


def test_after_a_failure_it_says_where_it_stopped(panel):
    progress = pending(6)
    progress[:2] = [replace(p, outcome=Outcome.DONE, elapsed_s=20.0) for p in progress[:2]]
    progress[2] = replace(progress[2], outcome=Outcome.FAILED, elapsed_s=30.0)
    panel.update(snap(70.0, RunState.FAILED, progress))
    assert panel.time_left.content == "stopped at subtask 3/6 after 1 min 10 s; 3 not run"


def test_the_estimate_never_exceeds_the_timeout(panel):
    for k in range(40):  # the error falls 1 mm every 0.1 s: 20 m to go would take half an hour
        active = replace(pending(1, timeout_s=60.0)[0], outcome=Outcome.ACTIVE, elapsed_s=20.0 + 0.1 * k,
                         position_error_m=20.0 - 0.01 * k)
        panel.update(snap(20.0 + 0.1 * k, RunState.RUNNING, [active]))
    text = panel.time_left.content
    assert "too slow to make it before the timeout" in text and "times out in 36 s" in text
    assert max(seconds_in(text)) <= 60.0 - 20.0


def test_no_path_and_blocked_are_said_in_the_list(panel):
    no_path = replace(pending(1)[0], outcome=Outcome.ACTIVE, no_path=True, position_error_m=3.0,
                      message="no path to the goal (3.00, 0.00) on the current map: holding here (Skip or Stop)")
    panel.update(snap(1.0, RunState.RUNNING, [no_path]))
    assert "no path to the goal" in panel.time_left.content and "no path to the goal" in panel.subtasks.content
    blocked = replace(no_path, no_path=False, blocked=Blocked(12.0, (1.0, 1.5), 0.4), message="blocked")
    panel.update(snap(13.0, RunState.RUNNING, [blocked]))
    assert "blocked: no progress for 12 s, 3.00 m from the goal; nearest obstacle" in panel.subtasks.content


def test_edits_during_a_run_apply_to_the_next_run(panel):
    active = replace(pending(2)[0], outcome=Outcome.ACTIVE, position_error_m=2.0)
    progress = [active, pending(2)[1]]
    panel.update(snap(1.0, RunState.RUNNING, progress, version=3))
    assert "next run" not in panel.time_left.content
    panel.update(snap(1.1, RunState.RUNNING, progress, version=4))  # a goal added while running
    assert "the edits run in the next run" in panel.time_left.content
    panel.update(snap(1.2, RunState.PAUSED, progress, version=5))  # paused or stopped: Start resumes this run
    assert "the edits run in the next run" in panel.time_left.content
    panel.update(snap(1.3, RunState.IDLE, progress, version=5))
    assert "the edits run in the next run" in panel.time_left.content
    panel.update(snap(1.4, RunState.RUNNING, progress, version=5))  # resumed: still the old run
    assert "the edits run in the next run" in panel.time_left.content
    panel.update(snap(1.5, RunState.IDLE, pending(3), version=5))  # Reset: the edited sequence is ready
    assert "next run" not in panel.time_left.content
    panel.update(snap(1.6, RunState.RUNNING, [replace(pending(3)[0], outcome=Outcome.ACTIVE)] + pending(3)[1:],
                      version=5))
    assert "next run" not in panel.time_left.content
