"""Localization in the live loops (real MuJoCo, real threads, object map in its own process, HTMPC): the
registrations run on the localization worker's thread, never on the mapping or control thread, and the corrections
they accept are applied by the io loop; with no frames and no control steps, the worker's timer still finds the pose
untrusted after `untrusted_after_s` and says so (a LOCALIZATION problem, the status line). No timing is asserted:
what runs where, and what the operator is told."""

from __future__ import annotations

import threading
import time
from collections import Counter
from dataclasses import replace

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from app.runtime.snapshot import RunState
from bench.localization import true_surface
from core.localization import global_search
from core.localization.gates import Verdict
from core.localization.localizer import Localizer
from core.params import LocalizationParams, SensorParams, SimParams
from core.robot.model import RobotModel
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from tests.app.bridge.conftest import wait_until
from tests.app.test_localization_health import HOLD
from tests.app.test_localization_loop import CORRIDOR, OUT_AND_BACK
from tests.app.test_localization_slip import AHEAD, SLIP_AT_S

pytestmark = pytest.mark.wallclock
SLOWER_SEARCH_S = 2.5
"""Added to each global search's wall time in the slip test (more than the plan's 2 s age limit)."""


@pytest.mark.slow
def test_live_registrations_run_on_their_own_thread_and_the_io_loop_applies_their_corrections(monkeypatch):
    """Driving the corridor live with localization on: every registration (`Localizer.correct`) ran on the
    "localization" thread, corrections were accepted, the io loop applied them (the estimate moved), and control
    steps went on meanwhile."""
    correct_threads: Counter[str] = Counter()
    apply_threads: Counter[str] = Counter()
    steps_at_registrations: list[int] = []
    correct, apply_due = Localizer.correct, Localizer.apply_due
    runtime: list[Runtime] = []

    def correct_on(self, *args, **kwargs):
        correct_threads[threading.current_thread().name] += 1
        steps_at_registrations.append(runtime[0].closed_loop.control_steps)
        return correct(self, *args, **kwargs)

    def apply_due_on(self, t):
        changed = apply_due(self, t)
        if changed:
            apply_threads[threading.current_thread().name] += 1
        return changed

    monkeypatch.setattr(Localizer, "correct", correct_on)
    monkeypatch.setattr(Localizer, "apply_due", apply_due_on)
    config = RuntimeConfig(map_kind="object", localization=LocalizationParams(enabled=True))
    rt = Runtime(config, scene=CORRIDOR, sequence=OUT_AND_BACK)
    runtime.append(rt)
    rt.closed_loop.reference_override = true_surface(rt)  # the true scene: corrections from the first frames
    try:
        rt.start_live()
        rt.start()
        loop, live = rt.closed_loop, rt.live
        assert live is not None and live.localization is not None and loop.localization_worker is live.localization
        localizer = loop.localizer
        assert localizer is not None
        assert wait_until(lambda: localizer.counts[Verdict.ACCEPTED.value] >= 3 and sum(apply_threads.values()) >= 3,
                          timeout_s=90), (dict(localizer.counts), dict(apply_threads), rt.status_line())
        assert wait_until(lambda: len(set(steps_at_registrations)) > 3, timeout_s=60), \
            "control steps went on between the registrations"
        assert rt.fault is None, rt.fault
    finally:
        rt.shutdown()
    assert set(correct_threads) == {"localization"}, correct_threads
    assert live.localization.threads == {"localization"}
    assert set(apply_threads) == {"io"}, apply_threads
    assert np.any(localizer.world_from_odom != 0.0), "the accepted corrections moved the estimate"


@pytest.mark.slow
def test_without_frames_or_control_steps_the_health_timer_finds_the_pose_untrusted():
    """A robot with no cameras, its run never started (no control step): after `untrusted_after_s` of robot time
    without an accepted correction the pose is untrusted, recorded once as a problem and said in the status line."""
    config = RuntimeConfig(map_kind="object", sim=SimParams(),
                           localization=replace(LocalizationParams(enabled=True), untrusted_after_s=1.0))
    world = SimWorld(RobotModel(config.robot), config.sim, CORRIDOR)
    rt = Runtime(config, sequence=HOLD, backend=SimRobot(world, cameras=()))
    try:
        rt.start_live()
        live = rt.live
        assert live is not None and live.localization is not None
        assert wait_until(lambda: rt.problems.count(ProblemKind.LOCALIZATION) == 1, timeout_s=60), \
            (rt.time, rt.status_line())
        health = rt.snapshot().localization
        assert health is not None and health.untrusted is not None
        assert health.untrusted.startswith("no correction accepted for"), health.untrusted
        assert "localization untrusted" in rt.status_line()
        assert rt.closed_loop.control_steps == 0 and not rt.closed_loop.latest_frames
        assert live.localization.registrations == 0 and live.localization.health_checks > 0
    finally:
        rt.shutdown()


@pytest.mark.slow
def test_live_a_slip_holds_the_base_for_the_search_without_counting_the_hold_as_late_control(monkeypatch):
    """The slip of `test_localization_slip.py` (0.5 m sideways while driving out), live at speed 1: the localizer
    gets lost, the base is held while the global search runs on the localization thread (seconds of wall time, longer
    than the plan's age limit), and the run goes on once it is found again. Holding is what the control loop decided
    at every step meanwhile, not a control loop gone quiet, so it is no "control is late" fault (the studio, live,
    faulted so during a search before). The search is made 2.5 s slower than it is (a loaded machine's: the studio
    beside a browser measured 2.8 s), so that the hold outlasts the age limit on any machine."""
    search = global_search.search

    def slow_search(*args, **kwargs):
        time.sleep(SLOWER_SEARCH_S)
        return search(*args, **kwargs)

    monkeypatch.setattr(global_search, "search", slow_search)
    sensor = replace(SensorParams(), slip_at_s=SLIP_AT_S, slip_m=(0.0, 0.5))
    config = RuntimeConfig(map_kind="object", seed=3, sim=replace(SimParams(), sensor=sensor),
                           localization=LocalizationParams(enabled=True))
    rt = Runtime(config, scene=AHEAD, sequence=OUT_AND_BACK)
    try:
        rt.start_live()
        rt.start()
        loop, localizer = rt.closed_loop, rt.closed_loop.localizer
        assert localizer is not None

        def held() -> bool:
            with localizer.lock:
                return bool(localizer.lost.episodes)

        assert wait_until(held, timeout_s=60), rt.status_line()
        live = rt.live
        assert live is not None
        steps_when_lost = live.control_steps

        def ended() -> bool:
            with localizer.lock:
                return np.isfinite(localizer.lost.episodes[0].anchored_t) or loop.fault_reason is not None

        assert wait_until(ended, timeout_s=120), rt.status_line()
        assert loop.fault_reason is None, loop.fault_reason
        episode = localizer.lost.episodes[0]
        assert live.control_steps > steps_when_lost, "the control loop went on ticking while the base was held"
        assert episode.searches and episode.searches[-1][1].unique
        assert wait_until(lambda: loop.run_state != RunState.RUNNING, timeout_s=120), rt.status_line()
        assert loop.fault_reason is None and loop.run_state == RunState.FINISHED, (loop.fault_reason, rt.status_line())
    finally:
        rt.shutdown()
