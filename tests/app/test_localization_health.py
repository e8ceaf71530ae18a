
"""The health the operator sees (issue 28, item 2) in the lockstep closed loop (real MuJoCo, object map, HTMPC,
localization on): the snapshot carries the pose's covariance, the registrations' verdicts and the age of the last
correction; corrections starved (every registration refused) make the pose untrusted, a LOCALIZATION problem in
the panel's counts, the run report and the status line; and the controller keeps delta_safe grown by the
uncertainty, measured at the robot's true clearance against the same run with `grow_margin` off."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from app.recording.report import write_report
from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from bench.localization import true_surface
from core.params import LocalizationParams, SensorParams, SimParams
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.test_localization_loop import CORRIDOR

HOLD = TaskSequence(subtasks=[BaseSubtask(name="hold", target=BasePose(x=0.0, y=0.0), timeout_s=60.0)])
STARVED = LocalizationParams(enabled=True, min_source_points=10**7, min_trusted_points=0)
"""No registration can pass (too few points in every frame: nothing to register), odometry alone in charge."""
REFUSED = LocalizationParams(enabled=True, max_iterations=0, min_trusted_points=0)
"""Every registration refused by a gate (not converged: no iteration allowed), odometry alone in charge."""
BOX_AHEAD = Scene((Box("ahead", (2.0, 0.0, 0.3)),), robot_start=(0.0, 0.0, 0.0))
"""One 0.6 m box, its near face at x = 1.7."""
UP_TO_THE_BOX = TaskSequence(subtasks=[BaseSubtask(name="up to the box", target=BasePose(x=0.9, y=0.0),
                                                   timeout_s=60.0)])
"""A goal whose base front (0.48 m ahead of its centre) stays 0.32 m from the box: reachable with delta_safe 0.25 m."""


def _runtime(localization: LocalizationParams, scene: Scene, sequence: TaskSequence) -> Runtime:
    config = RuntimeConfig(map_kind="object", sim=replace(SimParams(), sensor=SensorParams.ideal()),
                           localization=localization)
    return Runtime(config, scene=scene, sequence=sequence)


@pytest.mark.slow
def test_the_snapshot_carries_the_pose_health_with_corrections_accepted():
    rt = _runtime(LocalizationParams(enabled=True), CORRIDOR, HOLD)
    rt.closed_loop.reference_override = true_surface(rt)  # registration against the scene itself
    rt.run_lockstep(4.0, until_done=False)
    snap = rt.snapshot()
    h = snap.localization
    assert h is not None and snap.base_estimate is not None and snap.base_true is not None
    assert h.covariance.shape == (3, 3) and np.all(np.linalg.eigvalsh(h.covariance) > 0)
    assert h.sigma_xy_m == pytest.approx(np.sqrt(np.linalg.eigvalsh(h.covariance[:2, :2]).max()))
    assert h.accepted >= 5 and h.accepted_per_s > 0 and h.last_accepted_t is not None
    assert 0 <= h.since_accepted_s < 1.0, h
    assert h.untrusted is None and h.margin_growth_m == 0.0
    assert rt.closed_loop.problems.count(ProblemKind.LOCALIZATION) == 0
    assert rt.controller.delta_safe_m == rt.config.htmpc.delta_safe_m
    assert "localization untrusted" not in rt.status_line()


def test_without_localization_the_snapshot_has_no_health():
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=BOX_AHEAD, sequence=HOLD)
    assert rt.snapshot().localization is None


@pytest.mark.slow
def test_corrections_starved_past_untrusted_after_s_is_a_problem_with_its_reason(tmp_path):
    """Standing still, odometry does not drift (σ stays small: no margin grows), but every registration is refused:
    after `untrusted_after_s` the pose is untrusted, said in the status line, counted once as a problem with its
    reason, and written into the run report."""
    rt = _runtime(replace(REFUSED, untrusted_after_s=3.0), BOX_AHEAD, HOLD)
    rt.run_lockstep(2.5, until_done=False)
    assert rt.closed_loop.problems.count(ProblemKind.LOCALIZATION) == 0
    h = rt.snapshot().localization
    assert h is not None and h.untrusted is None and h.accepted == 0 and h.rejected >= 10
    rt.run_lockstep(2.0, until_done=False)
    snap = rt.snapshot()
    h = snap.localization
    assert h is not None and h.untrusted is not None and h.untrusted.startswith("no correction accepted for")
    assert h.margin_growth_m == 0.0 and h.last_accepted_t is None and h.since_accepted_s > 3.0
    problems = {p.kind: p for p in snap.problems}
    p = problems[ProblemKind.LOCALIZATION]
    assert p.count == 1 and 3.0 < p.first_t < 3.5, p
    assert "rejected" in p.last_message and "since the start" in p.last_message, p.last_message
    assert "localization untrusted: no correction accepted" in snap.status
    write_report(tmp_path, rt.log, (), {}, rt.closed_loop.problems)
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["problems"]["localization"]["count"] == 1
    assert report["summary"]["problems_localization"] == 1.0


@pytest.mark.slow
def test_standing_still_with_nothing_to_register_is_no_untrusted_pose():
    """The same stand with frames that have nothing to register (too few points, as at a face at arm's length):
    the base at rest does not drift and nothing doubts its pose, so past `untrusted_after_s` it is still trusted,
    the time at rest reported apart; no problem recorded."""
    rt = _runtime(replace(STARVED, untrusted_after_s=3.0), BOX_AHEAD, HOLD)
    rt.run_lockstep(4.5, until_done=False)
    h = rt.snapshot().localization
    assert h is not None and h.accepted == 0 and h.no_reference >= 10 and h.rejected == 0
    assert h.since_accepted_s > 4.0 and h.at_rest_s > 3.0, h
    assert h.untrusted is None, h.untrusted
    assert rt.closed_loop.problems.count(ProblemKind.LOCALIZATION) == 0
    assert "localization untrusted" not in rt.status_line()


@pytest.mark.slow
@pytest.mark.parametrize("grow", [True, False])
def test_an_untrusted_pose_grows_delta_safe_and_the_robot_keeps_it_from_the_box(grow):
    """The filter told its odometry drifts 0.2 m/√m and no correction is ever accepted: after 0.5 m σ_xy ≈ 0.14 m,
    3σ past delta_safe / 2. With `grow_margin` the controller keeps delta_safe + clip(3σ − delta_safe/2, 0, 0.3 m)
    (0.55 m once capped) at every step, and the planner grows its obstacles as much, so the goal (within the grown
    margin of the box) is moved back to where the margin holds and the operator told (measured: margin 0.540 m, goal
    moved 0.25 m, clearance 0.733 m at rest; before the planner followed the margin, the controller alone held the
    base 0.550 m from the box, short of the goal, until the timeout); without it, delta_safe stays 0.25 m and
    the robot drives on to the goal (measured: 0.446 m, at x = 0.76 m, the sequence finished)."""
    localization = replace(STARVED, drift_m_per_sqrt_m=0.2, grow_margin=grow)
    rt = _runtime(localization, BOX_AHEAD, UP_TO_THE_BOX)
    delta = rt.config.htmpc.delta_safe_m
    steps: list[tuple[float, float, float]] = []

    def track(r: Runtime) -> None:
        h = r.closed_loop.health(r.state.t)
        assert h is not None and r.world is not None
        steps.append((r.controller.delta_safe_m, h.margin_growth_m, r.world.robot_box_distance()[0]))

    rt.run_lockstep(10.0, until_done=False, on_control=track)
    kept, growth, clearance = (np.array(c) for c in zip(*steps, strict=True))
    assert rt.closed_loop.problems.count(ProblemKind.LOCALIZATION) == 1
    assert rt.world is not None and not rt.world.collisions
    if grow:
        # the health the step read is the one published: delta_safe kept = configured + growth (to the step's time)
        np.testing.assert_allclose(kept[1:], delta + growth[1:], atol=0.02)
        # grown near its cap (σ grows only while the base drives, and the planner, grown as much, stops it short)
        assert delta + localization.margin_growth_max_m - 0.02 < kept[-1] <= delta + localization.margin_growth_max_m
        assert clearance.min() > kept[-1] - 0.02, (clearance.min(), kept[-1])
        assert f"delta_safe 0.25 → {kept[-1]:.2f} m" in rt.status_line(), rt.status_line()
        # the goal, within the grown margin of the box, was moved back to where the margin holds, and said so
        shift = rt.sequencer.progress[0].goal_shift
        assert shift is not None and math.dist(shift.original, shift.driven) > 0.2, shift
    else:
        assert np.all(kept == delta) and np.all(growth == 0.0)
        assert clearance.min() < delta + localization.margin_growth_max_m - 0.05, clearance.min()
        assert rt.sequencer.finished
