"""Localization in the lockstep closed loop (real MuJoCo, sensor model, object map, HTMPC): the loop re-poses
state, frames and commands with T_world←odom; a drifting odometry is pulled back, a box moved in view does not
drag the pose and loses consistency, a floor-only view corrects nothing, failed registrations leave odometry
in charge, counted."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from multiprocessing import get_context

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from bench.localization import lap_against_odometry, true_surface
from core.localization.gates import Verdict
from core.params import LocalizationParams, SensorParams, SimParams
from core.scene import Box, Scene
from core.types import LocalizationStatus
from tasks import BasePose, BaseSubtask, TaskSequence, Tolerance

CORRIDOR = Scene(tuple(Box(f"b{i}", (x, y, 0.3)) for i, (x, y) in enumerate(
    [(-1.0, 1.3), (0.8, 1.3), (2.6, 1.3), (-1.0, -1.3), (0.8, -1.3), (2.6, -1.3), (4.4, 0.0), (-2.8, 0.0)])),
    name="corridor")
"""Boxes along both sides of a corridor and at both ends: every direction of x, y, yaw seen most of the time."""
OUT_AND_BACK = TaskSequence(subtasks=[
    BaseSubtask(name="out", target=BasePose(x=2.8, y=0.0, yaw_deg=0.0), tolerance=Tolerance(position_m=0.15),
                timeout_s=40.0),
    BaseSubtask(name="back", target=BasePose(x=-0.5, y=0.0, yaw_deg=180.0), tolerance=Tolerance(position_m=0.15),
                timeout_s=40.0)])
DRIFTY = replace(SensorParams(), odometry_drift_m=0.05, odometry_drift_rad=0.05)
"""Odometry five times worse than the default: a short lap drifts as the aisle's laps do."""
KNOWN_DRIFT = LocalizationParams(enabled=True, drift_m_per_sqrt_m=0.05, drift_rad_per_sqrt_rad=0.05, rate_hz=5.0,
                                 sigma_xy_m=0.01, sigma_yaw_rad=0.003, freeze_reference=False)
"""Localization that knows how its odometry drifts, registering at 5 Hz against the scene itself (a reference
good to about a centimetre, so measurements are trusted to 1 cm / 0.17°; not frozen: the scene is exact)."""


def _runtime(sensor: SensorParams, localization: LocalizationParams, scene: Scene = CORRIDOR,
             sequence: TaskSequence = OUT_AND_BACK, seed: int = 3) -> Runtime:
    config = RuntimeConfig(map_kind="object", seed=seed, sim=replace(SimParams(), sensor=sensor),
                           localization=localization)
    return Runtime(config, scene=scene, sequence=sequence)


def _errors(rt: Runtime, duration_s: float) -> np.ndarray:
    """x-y error of the loop's pose against the truth at every control step of a lockstep run."""
    errors: list[float] = []

    def track(r: Runtime) -> None:
        truth = r.backend.true_state().q[:2]  # type: ignore[attr-defined]
        errors.append(float(np.linalg.norm(r.state.q[:2] - truth)))

    rt.run_lockstep(duration_s, on_control=track)
    return np.array(errors)


def _errors_beside_odometry(rt: Runtime, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """x-y errors against the truth at every control step of a lockstep run: the loop's (localized) pose, and the
    same run's odometry pose (the localizer's T_world←odom undone), so both follow one trajectory."""
    localized, odometry = [], []

    def track(r: Runtime) -> None:
        truth = r.backend.true_state().q[:2]  # type: ignore[attr-defined]
        loc = r.closed_loop.localizer
        assert loc is not None
        x, y, yaw = loc.world_from_odom
        c, s = np.cos(yaw), np.sin(yaw)
        d = r.state.q[:2] - (x, y)
        odom = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        localized.append(float(np.linalg.norm(r.state.q[:2] - truth)))
        odometry.append(float(np.linalg.norm(odom - truth)))

    rt.run_lockstep(duration_s, on_control=track)
    return np.array(localized), np.array(odometry)


@pytest.mark.slow
def test_localization_against_the_scene_at_least_halves_the_drift_of_odometry_alone():
    """Odometry's error grows with the distance driven; the localized pose's must not: at the end of the run it is
    under half of the same run's odometry error, and never as large as odometry's worst. The issue's target (within
    5 cm where odometry drifts past 15 cm) is not reached yet (issue 25 stays open): localized max 8.7 cm measured
    with a control step on each new map (8.1 cm with the periodic step)."""
    rt = _runtime(DRIFTY, KNOWN_DRIFT)
    rt.closed_loop.reference_override = true_surface(rt)  # registration against the scene itself
    localized, odometry = _errors_beside_odometry(rt, 60.0)
    assert odometry.max() > 0.12, f"the premise: odometry drifts past 12 cm (max {odometry.max():.3f} m)"
    loc = rt.closed_loop.localizer
    assert loc is not None and loc.counts[Verdict.ACCEPTED.value] > 10
    summary = (f"localized max {localized.max():.3f} m, at the end {localized[-1]:.3f} m; odometry max "
               f"{odometry.max():.3f} m, at the end {odometry[-1]:.3f} m")
    assert localized[-1] < 0.5 * odometry[-1] and localized.max() < odometry.max(), summary


@pytest.mark.slow
def test_localization_against_the_self_built_map_bounds_the_drift_odometry_alone_exceeds():
    """E4's aisle lap 1 on four seeds (whole sensor model, object map, HTMPC), registering against the map the run
    builds itself (no prior map, no oracle), each against the same run's wheel odometry (same path, same random
    walk). Measured 2026-11-27 (docs/decisions.md, "A moved box pulled a right pose"): localized RMSE 14.0 / 4.2 /
    7.6 / 8.0 cm against odometry 10.9 / 15.0 / 8.0 / 5.6 cm, max 27.6 / 8.3 / 14.8 / 14.4 against 32.5 / 23.1 / 19.8
    / 11.3 cm. On a single seed either can win (a self-built reference follows the drift where it is new, and
    registrations against faces fitted a degree off pull the heading), so the property is asserted over the seeds:
    the mean RMSE below odometry's and the worst error below odometry's worst. The issue's 5 cm / 15 cm stay open."""
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:  # the seeds are independent runs
        laps = list(pool.map(lap_against_odometry, range(4)))
    rmse_loc, rmse_odo = [lap["rmse_m"] for lap in laps], [lap["odometry_rmse_m"] for lap in laps]
    max_loc, max_odo = [lap["max_m"] for lap in laps], [lap["odometry_max_m"] for lap in laps]
    accepted = sum(lap["accepted"] for lap in laps)
    summary = f"RMSE {np.round(rmse_loc, 3)} against odometry {np.round(rmse_odo, 3)}, max {np.round(max_loc, 3)} " \
              f"against {np.round(max_odo, 3)}"
    assert max(max_odo) > 0.15, f"the premise: odometry alone drifts past 0.15 m ({summary})"
    assert accepted > 200, summary
    assert np.mean(rmse_loc) < np.mean(rmse_odo), summary
    assert max(max_loc) < max(max_odo), summary


@pytest.mark.slow
def test_a_box_moved_in_view_does_not_move_the_estimate_and_its_consistency_drops():
    hold = TaskSequence(subtasks=[BaseSubtask(name="hold", target=BasePose(x=0.0, y=0.0, yaw_deg=0.0),
                                              timeout_s=60.0)])
    scene = replace(CORRIDOR, boxes=(*CORRIDOR.boxes, Box("ahead", (1.8, 0.4, 0.3))))
    # the reference is taken once (at the first registration) and kept: the box moves while the reference still
    # holds it at its old place (the map's own registration may re-place it meanwhile)
    rt = _runtime(SensorParams(), LocalizationParams(enabled=True, reference_period_s=3.0), scene=scene,
                  sequence=hold)
    rt.run_lockstep(3.6, until_done=False)
    loop, loc = rt.closed_loop, rt.closed_loop.localizer
    assert loc is not None and loc.status == LocalizationStatus.LOCALIZED
    before = loc.world_from_odom
    box = rt.world.box("ahead") if rt.world else None
    assert box is not None
    mapped = min(rt.map.snapshot().objects, key=lambda o: np.linalg.norm(o.pose[:2, 3] - box.position[:2]))
    ev_before = mapped.consistency
    rt.move_box("ahead", (box.position[0] + 0.1, box.position[1], box.position[2]))
    rt.run_lockstep(2.0, until_done=False)
    after = loc.world_from_odom
    assert np.linalg.norm(after[:2] - before[:2]) <= 0.01 and abs(after[2] - before[2]) < np.radians(0.5)
    assert any(mapped.id in c.disagreeing for c in loc.corrections), "the moved box should disagree"
    now = {o.id: o for o in loop.map.snapshot().objects}
    assert mapped.id not in now or now[mapped.id].consistency < ev_before


@pytest.mark.slow
def test_a_floor_only_view_corrects_nothing():
    drive = TaskSequence(subtasks=[BaseSubtask(name="out", target=BasePose(x=2.0, y=0.0), timeout_s=30.0)])
    rt = _runtime(DRIFTY, LocalizationParams(enabled=True, min_trusted_points=0), scene=Scene(), sequence=drive)
    rt.run_lockstep(8.0)
    loc = rt.closed_loop.localizer
    assert loc is not None and loc.counts[Verdict.DEGENERATE.value] >= 5
    assert loc.counts[Verdict.ACCEPTED.value] == 0 and not np.any(loc.world_from_odom)
    assert loc.status == LocalizationStatus.ODOMETRY


@pytest.mark.slow
def test_registration_failures_leave_odometry_in_charge_and_are_counted():
    rt = _runtime(DRIFTY, LocalizationParams(enabled=True, min_source_points=10**7, min_trusted_points=0))
    gaps: list[float] = []
    errors: list[float] = []

    def track(r: Runtime) -> None:
        odometry = r.backend.state().q[:3]  # type: ignore[attr-defined]  # the backend's own estimate
        gaps.append(float(np.max(np.abs(r.state.q[:3] - odometry))))
        errors.append(float(np.linalg.norm(odometry[:2] - r.backend.true_state().q[:2])))  # type: ignore[attr-defined]

    rt.run_lockstep(8.0, on_control=track)
    loc = rt.closed_loop.localizer
    assert loc is not None and loc.counts[Verdict.TOO_FEW_POINTS.value] >= 10
    assert loc.counts[Verdict.ACCEPTED.value] == 0 and not np.any(loc.world_from_odom)
    assert loc.status == LocalizationStatus.ODOMETRY
    assert len(gaps) >= 70 and max(errors) > 0.05, "the premise: odometry drifts"
    # at every control step the loop's pose is odometry's own (compared within one run: two lockstep runs may
    # part by a centimetre once a rounding difference flips a discrete choice of the map or the solver)
    assert max(gaps) < 1e-9
