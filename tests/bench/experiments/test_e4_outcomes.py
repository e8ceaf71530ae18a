"""E4's run of a sequence: subtasks the run never reached are reported with why, not left out of the report."""

from __future__ import annotations

from app.runtime import Runtime
from bench.experiments.e4_long_term import LAPS, lap_sequence, layouts, run_sequence, scene
from bench.experiments.trials import runtime_config


def test_subtasks_the_run_did_not_reach_are_outcomes_with_the_reason() -> None:
    """A lap given 2 s: the first drive cannot finish, and every subtask after it is reported not reached."""
    seq = lap_sequence(1)
    rt = Runtime(runtime_config(map_kind="ground_truth", seed=0), scene=scene(layouts(0, LAPS)[0]), sequence=seq)
    outcomes = run_sequence(rt, seq, 2.0, lambda _rt: None)
    assert [o["name"] for o in outcomes] == [s.name for s in seq.subtasks]
    assert all(o["outcome"] == "not_reached" for o in outcomes)
    assert all(o["message"].startswith("not reached: out of the run's time at t = 2.0 s") for o in outcomes), outcomes
