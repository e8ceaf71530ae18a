"""Loop closure in the lockstep closed loop (real MuJoCo, sensor model with a drifting odometry, object map, HTMPC,
registration against the map the run builds itself): back at the start after a lap, the frames registered against the
keyframes kept there pull the pose back towards the truth along the directions those keyframes constrain, which the
map's own surfaces (placed by the drifting pose) did not."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from core.angles import wrap_angle
from core.params import LocalizationParams, SensorParams, SimParams
from tasks import BasePose, BaseSubtask, TaskSequence, Tolerance
from tests.app.test_localization_loop import CORRIDOR

LAP = TaskSequence(subtasks=[
    BaseSubtask(name="out", target=BasePose(x=2.8, y=0.0, yaw_deg=0.0), tolerance=Tolerance(position_m=0.15),
                timeout_s=40.0),
    BaseSubtask(name="back", target=BasePose(x=-0.5, y=0.0, yaw_deg=180.0), tolerance=Tolerance(position_m=0.15),
                timeout_s=40.0),
    BaseSubtask(name="again", target=BasePose(x=1.3, y=0.0, yaw_deg=0.0),
                tolerance=Tolerance(position_m=0.1, orientation_deg=10.0), timeout_s=30.0)])
"""Out along the corridor, back past the start with a half turn, and out again, facing as at the start: the last
stretch sees what the first keyframes saw (the first are kept ~1.1 m out, once the boxes are trusted)."""
DRIFTY = replace(SensorParams(), odometry_drift_m=0.05, odometry_drift_rad=0.05)
LOOPS = LocalizationParams(enabled=True, loop_closure=True, loop_min_age_s=20.0, drift_m_per_sqrt_m=0.05,
                           drift_rad_per_sqrt_rad=0.05)
"""Localization that knows how its odometry drifts, closing loops onto keyframes at least 20 s old (the lap is short:
the half turn's keyframes, 14–19 s in, are not the earlier visit)."""
HEADING_SWING_DEG = 3.0
"""How much worse the heading may end than before the closure: the view constrains x, and the graph moving 19 cm of x
over the lap's chain turned the heading by 2.5 deg one way (AMD EPYC) and 3.2 deg the other (Intel Xeon)."""


@pytest.mark.slow
def test_back_at_the_start_a_loop_closure_pulls_the_pose_back_along_what_its_keyframes_see():
    """Measured (lockstep, deterministic): the lap ends at the start at 15 s, before the first keyframes (2-5 s in) are
    20 s old, so the closures come from the base standing there. The first keyframes hold one trusted surface, the
    corridor's end box's face (the side boxes were not trusted yet): a closure onto them constrains the distance to it
    (x) and hardly y. Before the first closure (22.3 s) the pose is 27.5 cm off, (-23.7, +14.0) cm and -7.2 deg;
    the closure takes x to 0.1 cm and the heading to -4.0 deg, and the graph, turning the lap's chain by that 3 deg,
    moves the base 6 cm further off in y (nothing in that view measures y): the norm ends at 19.7 cm. (Before the
    carving checks were counted per camera, 83487df, the same run was 30.8 cm off before and 14.4 cm at the end,
    y then moving 6 cm the other way; with a factor every 2 s while standing, the fourth round's rule, 22.7 cm.)
    The heading is not what this view measures: on an AMD EPYC the same run (lockstep repeats per CPU) is 27.8 cm
    and -7.4 deg off before the closure (22.5 s), whose one constrained direction is (x, y, L yaw) = (-0.996, 0.04,
    0.07) with the other two at 0.0 and 1.4 of the 2.0 information floor; x goes to -4.5 cm, and the graph, spreading
    the 19 cm it moved over the lap's chain, turns the heading to -10.0 deg (-9.0 at the end, 12.4 cm): the Xeon's
    run turned it 3 deg the other way. So the test holds what a closure onto that view must do: x pulled back, the
    norm down, and the heading, which it barely constrains, not swung by more than 3 deg either way."""
    config = RuntimeConfig(map_kind="object", seed=3, sim=replace(SimParams(), sensor=DRIFTY), localization=LOOPS)
    rt = Runtime(config, scene=CORRIDOR, sequence=LAP)
    rows: list[tuple[float, np.ndarray]] = []

    def track(r: Runtime) -> None:
        truth = r.backend.true_state().q[:3]  # type: ignore[attr-defined]
        error = r.state.q[:3] - truth
        rows.append((r.time, np.array([error[0], error[1], wrap_angle(float(error[2]))])))

    rt.run_lockstep(40.0, on_control=track, until_done=False)  # the lap takes ~15 s; then it stands at home
    loc = rt.closed_loop.localizer
    assert loc is not None and loc.loops is not None
    loops = [c for c in loc.corrections if c.loop and c.apply_t == c.apply_t]
    assert loops and loc.loops.graph.count("loop") >= 1, f"no loop closure accepted: {dict(loc.counts)}"
    t = np.array([r[0] for r in rows])
    err = np.array([r[1][:2] for r in rows])
    heading = np.array([r[1][2] for r in rows])
    first = loops[0].apply_t
    before = err[t < first][-1]
    after = err[-1]
    summary = (f"error before the first loop closure ({first:.1f} s) {np.round(before, 3)} m, "
               f"at the end {np.round(after, 3)} m")
    premise = "the premise: the lap drifted, along x too; "
    assert np.linalg.norm(before) > 0.15 and abs(before[0]) > 0.15, premise + summary
    assert abs(after[0]) < 0.5 * abs(before[0]), "pulled back along what the keyframes constrain; " + summary
    assert np.linalg.norm(after) < 0.8 * np.linalg.norm(before), "the norm comes down too; " + summary
    heading_before = abs(heading[t < first][-1])
    assert abs(heading[-1]) <= heading_before + np.radians(HEADING_SWING_DEG), (
        f"the heading, which the closure barely constrains, is not swung: {np.degrees(heading_before):.1f} deg off "
        f"before, {np.degrees(abs(heading[-1])):.1f} at the end; " + summary)
