"""Start after an interruption (pause, stop, emergency stop) resumes the active subtask; Reset starts over.
The stale-state pause of the bridge: tests/app/bridge/test_bridge_start_resumes.py."""

from __future__ import annotations

import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from app.ui.run_panel import CONTROL_HINT, ESTOP_HINT
from core.scene import Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.sequencer import Outcome

TWO_LEGS = TaskSequence(subtasks=[BaseSubtask(name="first leg", target=BasePose(x=0.8, y=0.0)),
                                  BaseSubtask(name="second leg", target=BasePose(x=1.6, y=0.0))])


def _into_second_leg() -> Runtime:
    """A lockstep run on an empty scene stopped in its second subtask (the first done)."""
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene(), sequence=TWO_LEGS)
    for _ in range(30):
        rt.run_lockstep(0.5)
        if rt.sequencer.index == 1 and rt.sequencer.progress[1].elapsed_s > 0.3:
            return rt
    pytest.fail(f"the first leg did not end: {rt.status_line()}")


@pytest.mark.parametrize("interrupt", ["pause", "stop", "emergency_stop"])
def test_start_resumes_the_active_subtask(interrupt: str) -> None:
    rt = _into_second_leg()
    elapsed = rt.sequencer.progress[1].elapsed_s
    getattr(rt, interrupt)()
    assert rt.run_state == {"pause": RunState.PAUSED, "stop": RunState.IDLE,
                            "emergency_stop": RunState.ESTOP}[interrupt]
    rt.start()
    assert rt.run_state == RunState.RUNNING
    rt.run_lockstep(0.3)
    progress = rt.sequencer.progress
    assert rt.sequencer.index == 1 and progress[0].outcome == Outcome.DONE  # not back at the first leg
    assert progress[1].outcome in (Outcome.ACTIVE, Outcome.DONE)
    assert elapsed < progress[1].elapsed_s < elapsed + 1.0  # its clock went on from where it stood


@pytest.mark.parametrize("interrupt", ["pause", "stop"])
def test_an_edit_while_interrupted_waits_for_the_next_run(interrupt: str) -> None:
    """Paused (or stopped) mid-sequence and edited: Start resumes the run it interrupted (the second leg, not the
    edited sequence from its first subtask, as it did while the studio said the run goes on); the edit runs next."""
    rt = _into_second_leg()
    getattr(rt, interrupt)()
    assert rt.under_way
    edited = TWO_LEGS.model_copy(update={"subtasks": [*TWO_LEGS.subtasks,
                                                      BaseSubtask(name="third leg", target=BasePose(x=0.8, y=-0.8))]})
    rt.set_sequence(edited)
    assert len(rt.sequencer.progress) == 2 and rt.sequencer.index == 1  # the interrupted run, as it stood
    rt.start()
    rt.run_lockstep(60.0)
    assert rt.run_state == RunState.FINISHED and [p.name for p in rt.sequencer.progress] == ["first leg", "second leg"]
    assert not rt.under_way
    rt.start()  # the next run is the edited sequence
    assert [p.name for p in rt.sequencer.progress] == ["first leg", "second leg", "third leg"]


def test_reset_starts_over_and_start_after_the_end_runs_again() -> None:
    rt = _into_second_leg()
    rt.stop()
    rt.reset()
    assert rt.sequencer.index == 0 and {p.outcome for p in rt.sequencer.progress} == {Outcome.PENDING}
    rt.run_lockstep(60.0)
    assert rt.run_state == RunState.FINISHED
    rt.start()  # nothing to resume: the sequence runs again from its first subtask
    assert rt.sequencer.index == 0 and rt.run_state == RunState.RUNNING


def test_the_studio_says_start_resumes_and_reset_starts_over() -> None:
    for hint in (CONTROL_HINT, ESTOP_HINT):
        assert "Start resumes the" in hint and "Reset starts over" in hint
    assert all(word in CONTROL_HINT for word in ("Pause", "Stop", "emergency stop", "stale-state"))
