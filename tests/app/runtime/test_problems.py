"""The problems log: what it counts from controller steps, and its hook points in a real closed loop."""

import json
import time

import numpy as np
import pytest

from app.recording.report import write_report
from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind, ProblemLog, summary_line
from app.runtime.snapshot import RunState
from core.scene import Scene
from core.types import Plan, PlanReason, PlanStatus
from tasks import BasePose, BaseSubtask, TaskSequence

GOAL = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.0, y=0.0), timeout_s=30.0)])


def plan(status: PlanStatus, message: str = "", reason: PlanReason = PlanReason.NONE) -> Plan:
    z = np.zeros((11, 9))
    return Plan(0.0, 0.3, z, z, z[:10], z[:, :3], z[:, :3], (0.0,), (1.0,), status, message, reason)


def test_plan_classification():
    log = ProblemLog(slow_solve_ms=100.0)
    log.observe_plan(plan(PlanStatus.OK), 0.1, 5.0)
    log.observe_plan(plan(PlanStatus.STOPPING, "no task: holding", PlanReason.NO_TASK), 0.2)
    assert log.counts() == ()
    log.observe_plan(plan(PlanStatus.OK, "level 2 QP failed (1)", PlanReason.QP_FAILED), 1.0, 5.0)  # level 1 kept
    log.observe_plan(plan(PlanStatus.FALLBACK, "level 1 QP failed (1); braking along the previous plan",
                          PlanReason.QP_FAILED), 2.0)
    log.observe_plan(plan(PlanStatus.FALLBACK, "solve took 312 ms > 250 ms; braking", PlanReason.SOLVE_TIMEOUT),
                     3.0, 312.0)
    log.observe_plan(plan(PlanStatus.OK), 4.0, 180.0)
    by_kind = {c.kind: c for c in log.counts()}
    assert by_kind[ProblemKind.QP_FAILURE].count == 2 and by_kind[ProblemKind.QP_FAILURE].first_t == 1.0
    assert by_kind[ProblemKind.FALLBACK].count == 2 and by_kind[ProblemKind.FALLBACK].last_t == 3.0
    assert by_kind[ProblemKind.SLOW_SOLVE].count == 2
    assert by_kind[ProblemKind.SLOW_SOLVE].last_message == "solve took 180 ms (> 100 ms)"
    assert log.total == 6
    assert summary_line(log.counts()).startswith("2 QP failures (last at 2.0 s), 2 fallback plans")
    table = json.loads(json.dumps(log.to_json()))
    assert table["qp_failure"]["count"] == 2
    assert list(table) == [k.value for k in ProblemKind]  # every kind, with its count
    assert table["watchdog"] == {"count": 0, "first_t": None, "last_t": None, "last_message": ""}


def test_counts_follow_the_reason_not_the_wording():
    """Rewording a plan's message changes no count: the log reads `Plan.reason` (issue 24, typed reasons)."""
    log = ProblemLog(slow_solve_ms=100.0)
    log.observe_plan(plan(PlanStatus.OK, "QP failed? solve took? no task?"), 0.1, 5.0)  # words alone: nothing
    log.observe_plan(plan(PlanStatus.STOPPING, "holding", PlanReason.NO_TASK), 0.2)
    assert log.counts() == ()
    log.observe_plan(plan(PlanStatus.FALLBACK, "hpipm gave up", PlanReason.QP_FAILED), 1.0)
    log.observe_plan(plan(PlanStatus.FALLBACK, "too slow", PlanReason.SOLVE_TIMEOUT), 2.0, 300.0)
    log.observe_plan(plan(PlanStatus.STOPPING, "state was NaN", PlanReason.NON_FINITE_STATE), 3.0)
    by_kind = {c.kind: c.count for c in log.counts()}
    assert by_kind == {ProblemKind.QP_FAILURE: 1, ProblemKind.FALLBACK: 3, ProblemKind.SLOW_SOLVE: 1}


def test_plurals_and_a_threshold_never_read_as_equal():
    log = ProblemLog(slow_solve_ms=100.0)
    log.observe_plan(plan(PlanStatus.OK), 1.0, 100.3)
    (slow,) = log.counts()
    assert slow.last_message == "solve took 100.3 ms (> 100 ms)"
    assert summary_line(log.counts()) == "1 slow solve (last at 1.0 s)"
    log.observe_plan(plan(PlanStatus.OK), 2.0, 150.0)
    assert summary_line(log.counts()) == "2 slow solves (last at 2.0 s)"


def test_controller_problems_reach_the_snapshot_and_the_report(tmp_path):
    """Every controller step passes through the log: a failing solver shows in the snapshot and report.json."""
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene(), sequence=GOAL)
    solve = rt.controller.solve
    calls = {"n": 0}

    def flaky(state, refs, edf):
        calls["n"] += 1
        out = solve(state, refs, edf)
        if calls["n"] % 5 == 0:  # every fifth step: a level-1 QP failure and its braking plan
            return rt.controller._fallback(state, 2, PlanReason.QP_FAILED, "level 1 QP failed (3)")
        return out

    rt.controller.solve = flaky
    rt.run_lockstep(3.0, until_done=False)
    counts = {c.kind: c for c in rt.snapshot().problems}
    assert counts[ProblemKind.QP_FAILURE].count == calls["n"] // 5 > 0
    assert counts[ProblemKind.FALLBACK].count == calls["n"] // 5
    summary = write_report(tmp_path, rt.log, (), {"title": "t"}, rt.problems)
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["problems"]["qp_failure"]["count"] == calls["n"] // 5
    assert summary["problems_qp_failure"] == calls["n"] // 5 and summary["problems_fault"] == 0
    rt.reset()
    assert rt.snapshot().problems == ()


@pytest.mark.wallclock
@pytest.mark.slow
def test_a_crashed_live_loop_is_a_fault():
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene(), sequence=GOAL)

    def broken(observation):
        raise RuntimeError("map exploded")

    rt.map.integrate = broken
    rt.start_live()
    try:
        rt.start()
        deadline = time.time() + 20
        while time.time() < deadline and rt.problems.count(ProblemKind.FAULT) == 0:
            time.sleep(0.05)
        (fault,) = [c for c in rt.snapshot().problems if c.kind == ProblemKind.FAULT]
        assert "map exploded" in fault.last_message and rt.run_state != RunState.RUNNING
    finally:
        rt.shutdown()
