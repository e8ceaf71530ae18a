"""Localization: the base pose error over E4's aisle laps with and without `core/localization`, on the same seeds.

    python -m bench.localization [--quick]

The three-lap aisle run of E4 (`bench/experiments/e4_long_term.py`: its scene with the loose boxes, its lap
sequence) through the whole sensor model (depth noise, dropouts, flying pixels, odometry drift, camera time
offset), object map and HTMPC on. At every control step the x-y and heading error of the pose the loop uses
against the simulator's truth (no trajectory alignment): `ate_rmse_m`, `ate_max_m`, `final_error_m`, per lap
`ate_rmse_lap1_m` …, `rpe_per_10m` (error growth over 10 m driven), `heading_rmse_deg`; the registration's
time (`registration_ms_p50`/`_p95`, the reference's rebuild apart), its verdicts (`accepted`, `rejected`,
`degenerate`), and `false_corrections_pct`: accepted corrections that left the pose > 5 cm or 1° from the
truth, with 0 / 30 / 60 % of the boxes moved by 0.1 m and by 0.3 m at the start of laps 2 and 3
(`false_corrections_pct_<pct>_<cm>`; `false_corrections_pct` the worst). As defined it also counts corrections
made while the drift already exceeds 5 cm, so `pulled_away_pct` (same conditions) counts apart the accepted
corrections that moved the pose farther from the truth (> 1 cm or 0.2°): the false pulls. `_odom` figures are the
same run without localization. The control step's median with and without (`control_ms_median_*`).

`--quick`: one seed, lap 1, nothing moved: ATE and timing only. `--laps N` drives N laps (the quick run's
seed; `ate_rmse_lapK_m` per lap shows whether the error stops growing). `--reference scene` registers against
the true scene (an oracle map: what registration can do when the reference is right); the default, `map`, is
the self-built map as the loop has it (`oracle_reference` 0), the issue's condition. `--workers N` runs the
runs (3 seeds × (on, off, four moved conditions) in the full run) in N processes: the figures are the same
(lockstep), the timing ones then include the contention.
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from multiprocessing import get_context

import numpy as np
from rich.progress import Progress

from app.runtime import Runtime
from bench.experiments.e4_long_term import SEED, lap_sequence, layouts, run_sequence, scene
from bench.experiments.trials import quiet_logs, runtime_config
from bench.report import bench_args, percentile, write_result
from core.angles import wrap_angle
from core.localization import se2
from core.localization.gates import FAILURES, Verdict
from core.localization.localizer import DEGENERATE
from core.params import LocalizationParams
from core.scene import Box
from core.types import ReferenceSurface

log = logging.getLogger(__name__)

NAME = "localization"
LAP_S = 150.0
FALSE_M, FALSE_DEG = 0.05, 1.0
PULLED_M, PULLED_DEG = 0.01, 0.2
"""A correction that worsens the pose by more than this pulled it away (registration noise at 5 Hz is millimetres)."""
MOVES = ((0.0, 0.0), (0.3, 0.1), (0.6, 0.1), (0.3, 0.3), (0.6, 0.3))
"""(share of the boxes, metres) moved at the start of laps 2 and 3."""


class _Track:
    """`on_control`: the loop's pose and the truth at every control step, and the lap each belongs to."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, int, np.ndarray, np.ndarray, np.ndarray]] = []
        """(time, lap, estimate, truth, odometry): x, y, yaw each; odometry is the same run's wheel odometry in the
        world frame (the estimate without its corrections), so the two compare on one path and one drift."""
        self.lap = 0

    def __call__(self, rt: Runtime) -> None:
        truth = rt.backend.true_state().q[:3]  # type: ignore[attr-defined]
        estimate = rt.state.q[:3].copy()
        loc = rt.closed_loop.localizer
        odometry = estimate if loc is None else se2.compose(se2.inverse(loc.world_from_odom), estimate)
        self.rows.append((rt.time, self.lap, estimate, truth.copy(), odometry))


def move_boxes(rt: Runtime, share: float, distance_m: float, rng: np.random.Generator) -> int:
    """Move `share` of the scene's boxes by `distance_m` in a random horizontal direction (where allowed)."""
    assert rt.world is not None
    boxes = rt.world.boxes()
    moved = 0
    for box in rng.permutation(len(boxes))[: int(round(share * len(boxes)))]:
        b = boxes[int(box)]
        angle = rng.uniform(0, 2 * math.pi)
        x, y, z = b.position
        try:
            rt.move_box(b.id, (x + distance_m * math.cos(angle), y + distance_m * math.sin(angle), z))
            moved += 1
        except ValueError:
            continue
    return moved


def true_surface(rt: Runtime, step_m: float = 0.05) -> Callable[[float], ReferenceSurface]:
    """A reference of the true scene: the boxes' sides and tops sampled every step_m (an oracle map)."""
    assert rt.world is not None
    world = rt.world

    def surface(t: float) -> ReferenceSurface:
        parts = [box_surface(b, step_m) for b in world.boxes()]
        ids = np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)]) if parts else np.zeros(0, int)
        return ReferenceSurface(t, np.vstack(parts) if parts else np.zeros((0, 3)), ids.astype(int))
    return surface


def box_surface(b: Box, step_m: float) -> np.ndarray:
    """Points on the four sides and the top of a box, world frame."""
    hx, hy, hz = (s / 2 for s in b.size)
    u = np.arange(-1.0, 1.0 + 1e-9, step_m / max(hx, hy, hz, step_m))
    a, c = np.meshgrid(u, u)
    a, c = a.ravel(), c.ravel()
    one = np.ones_like(a)
    local = np.vstack([np.column_stack([s * hx * one, a * hy, c * hz]) for s in (-1, 1)]
                      + [np.column_stack([a * hx, s * hy * one, c * hz]) for s in (-1, 1)]
                      + [np.column_stack([a * hx, c * hy, hz * one])])
    T = b.pose()
    return local @ T[:3, :3].T + T[:3, 3]


def run(seed: int, laps: int, localize: bool, share: float = 0.0, distance_m: float = 0.0,
        oracle: bool = False, params: LocalizationParams | None = None) -> dict:
    """One run: the track of poses, the localizer's corrections and the control step's times (`oracle`: the
    localizer registers against the true scene instead of the map)."""
    params = replace(params or LocalizationParams(), enabled=localize)
    if oracle:
        params = replace(params, freeze_reference=False)  # the true scene is the reference as it is
    config = runtime_config(map_kind="object", seed=seed, localization=params)
    first = layouts(SEED, 1)[0]
    rt = Runtime(config, scene=scene(first), sequence=lap_sequence(1))
    if oracle:
        rt.closed_loop.reference_override = true_surface(rt)
    track, rng = _Track(), np.random.default_rng([seed, 7])
    completed = 0
    t0 = time.perf_counter()
    fault = None
    for lap in range(laps):
        track.lap = lap
        if lap and share > 0.0:
            move_boxes(rt, share, distance_m, rng)
        outcomes = run_sequence(rt, lap_sequence(1), LAP_S, track)
        completed += sum(o["outcome"] == "done" for o in outcomes)
        if rt.fault is not None:  # e.g. lost localization: the run stops there, as a run would; laps left count 0
            fault = f"lap {lap + 1}, t = {rt.time:.1f} s: {rt.fault}"
            log.warning("%s: %s", condition(seed, localize, share, distance_m), fault)
            break
    wall_s = time.perf_counter() - t0
    localizer = rt.closed_loop.localizer
    control = [t.get("control", math.nan) for t in rt.log.timings_ms]
    return {"rows": track.rows, "corrections": list(localizer.corrections) if localizer else [],
            "counts": dict(localizer.counts) if localizer else {}, "control_ms": control, "completed": completed,
            "wall_s": wall_s, "latency_s": rt.closed_loop.camera_latency_s(), "fault": fault}


def condition(seed: int, localize: bool, share: float, distance_m: float) -> str:
    """A run's seed and condition, as its faults name it."""
    return f"seed {seed}, localization {'on' if localize else 'off'}, {share:.0%} of the boxes moved by {distance_m} m"


def lap_against_odometry(seed: int) -> dict[str, float]:
    """One lap against the self-built map on `seed`, with the same run's odometry as the comparison: RMSE and max of
    the x-y error (m) localized and by odometry alone, and the accepted registrations (a process pool's worker)."""
    result = run(seed, 1, True)
    rows = result["rows"]
    localized = pose_errors(rows)[2]
    odometry = np.array([np.linalg.norm(r[4][:2] - r[3][:2]) for r in rows])
    return {"rmse_m": float(np.sqrt(np.mean(localized**2))), "max_m": float(localized.max()),
            "odometry_rmse_m": float(np.sqrt(np.mean(odometry**2))), "odometry_max_m": float(odometry.max()),
            "accepted": float(accepted(result))}


def accepted(result: dict) -> int:
    """How many of a run's registrations were accepted (the localizer's verdict counts)."""
    return result["counts"].get(Verdict.ACCEPTED.value, 0)


def pose_errors(rows: list) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times, laps, x-y error (m) and heading error (rad) of each control step."""
    t = np.array([r[0] for r in rows])
    lap = np.array([r[1] for r in rows])
    est, truth = np.array([r[2] for r in rows]), np.array([r[3] for r in rows])
    xy = np.linalg.norm(est[:, :2] - truth[:, :2], axis=1)
    yaw = np.array([wrap_angle(a) for a in est[:, 2] - truth[:, 2]])
    return t, lap, xy, yaw


def rpe_per_10m(rows: list) -> float:
    """Median growth of the x-y error over 10 m driven (truth path), per 10 m."""
    truth = np.array([r[3][:2] for r in rows])
    err = np.array([r[2][:2] - r[3][:2] for r in rows])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(truth, axis=0), axis=1))])
    growth = []
    for i in range(len(s)):
        j = int(np.searchsorted(s, s[i] + 10.0))
        if j >= len(s):
            break
        growth.append(float(np.linalg.norm(err[j] - err[i])))
    return float(np.median(growth)) if growth else math.nan


def ate_figures(result: dict, laps: int, suffix: str = "") -> dict[str, float]:
    _, lap, xy, yaw = pose_errors(result["rows"])
    heading_deg = float(np.degrees(np.sqrt(np.mean(yaw**2))))
    f = {f"ate_rmse_m{suffix}": float(np.sqrt(np.mean(xy**2))), f"ate_max_m{suffix}": float(xy.max()),
         f"final_error_m{suffix}": float(xy[-1]), f"heading_rmse_deg{suffix}": heading_deg,
         f"rpe_per_10m{suffix}": rpe_per_10m(result["rows"])}
    for k in range(laps):
        sel = lap == k
        f[f"ate_rmse_lap{k + 1}_m{suffix}"] = float(np.sqrt(np.mean(xy[sel] ** 2))) if sel.any() else math.nan
    f[f"completed{suffix}"] = float(result["completed"])
    return f


def correction_errors(result: dict) -> np.ndarray:
    """Per accepted correction: the x-y error (m) and heading error (deg) against the truth at the frame's exposure,
    before and after it (K×4: xy before, xy after, heading before, heading after)."""
    rows = result["rows"]
    t = np.array([r[0] for r in rows])
    truth = np.array([r[3] for r in rows])
    accepted = [c for c in result["corrections"] if c.verdict == Verdict.ACCEPTED and c.pose is not None]
    out = np.zeros((len(accepted), 4))
    for n, c in enumerate(accepted):
        te = c.t - result["latency_s"]
        true = np.array([np.interp(te, t, truth[:, i]) for i in range(2)])
        yaw = truth[int(np.clip(np.searchsorted(t, te), 0, len(t) - 1)), 2]
        before = se2.compose(se2.inverse(c.delta), c.pose)
        out[n] = (np.linalg.norm(before[:2] - true), np.linalg.norm(c.pose[:2] - true),
                  abs(math.degrees(wrap_angle(before[2] - yaw))), abs(math.degrees(wrap_angle(c.pose[2] - yaw))))
    return out


def false_corrections_pct(e: np.ndarray) -> float:
    """Of a run's accepted corrections (`correction_errors`), those whose corrected pose is > 5 cm or 1° from the
    truth at the frame's exposure (the issue's figure: it also counts a correction that made a pose already that far
    off better, or no worse)."""
    if not len(e):
        return math.nan
    return 100.0 * float(np.mean((e[:, 1] > FALSE_M) | (e[:, 3] > FALSE_DEG)))


def pulled_away_pct(e: np.ndarray) -> float:
    """Of a run's accepted corrections (`correction_errors`), those that moved the pose farther from the truth by
    > `PULLED_M` in x-y or > `PULLED_DEG` in heading: the false pulls (a moved box dragging the pose), apart from the
    drift a correction only failed to remove."""
    if not len(e):
        return math.nan
    return 100.0 * float(np.mean((e[:, 1] - e[:, 0] > PULLED_M) | (e[:, 3] - e[:, 2] > PULLED_DEG)))


def correction_figures(runs: list[dict]) -> tuple[float, float]:
    """`false_corrections_pct` and `pulled_away_pct`, each the mean over `runs` (each run's errors found once)."""
    errors = [correction_errors(x) for x in runs]
    return (float(np.nanmean([false_corrections_pct(e) for e in errors])),
            float(np.nanmean([pulled_away_pct(e) for e in errors])))


def registration_figures(result: dict) -> dict[str, float]:
    cs = result["corrections"]
    reg = [c.registration_ms for c in cs if math.isfinite(c.registration_ms)]
    ref = [c.reference_ms for c in cs if c.reference_ms > 0]
    counts = result["counts"]
    return {"registration_ms_p50": percentile(reg, 50), "registration_ms_p95": percentile(reg, 95),
            "reference_ms_p50": percentile(ref, 50),
            "accepted": float(accepted(result)),
            "rejected": float(sum(v for k, v in counts.items() if k not in (Verdict.ACCEPTED.value, DEGENERATE))),
            "failures": float(sum(counts.get(v.value, 0) for v in FAILURES)),
            "no_reference": float(counts.get(Verdict.NO_REFERENCE.value, 0)),
            "degenerate": float(counts.get(DEGENERATE, 0) + counts.get(Verdict.DEGENERATE.value, 0))}


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--laps", type=int, default=None, help="laps to drive (default: 1 quick, 3 full)")
    parser.add_argument("--reference", choices=("map", "scene"), default="map",
                        help="register against the self-built map (default) or the true scene (an oracle)")
    parser.add_argument("--workers", type=int, default=1,
                        help="processes running the runs side by side (timing figures then include contention)")


def _job(args: tuple[int, int, bool, float, float, bool]) -> dict:
    """`run` on one (seed, laps, localize, share, distance_m, oracle): a process pool's worker."""
    seed, laps, localize, share, distance_m, oracle = args
    quiet_logs()
    return run(seed, laps, localize, share, distance_m, oracle=oracle)


def run_all(jobs: list[tuple[int, int, bool, float, float, bool]], workers: int) -> list[dict]:
    """Every job's result, in order; `workers` > 1 runs them in a pool of processes (lockstep runs are
    deterministic, so the figures do not depend on it; the timing figures then include the contention)."""
    with Progress() as progress:
        task = progress.add_task("aisle runs", total=len(jobs))
        if workers <= 1:
            out = []
            for job in jobs:
                out.append(_job(job))
                progress.advance(task)
            return out
        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=get_context("spawn")) as pool:
            futures = [pool.submit(_job, job) for job in jobs]
            for _ in as_completed(futures):
                progress.advance(task)
            return [f.result() for f in futures]


def main(argv: list[str] | None = None) -> dict[str, float]:
    args = bench_args("Localization: the base pose error over the aisle laps, with and without", argv, _options)
    quiet_logs()
    seeds, laps = ((0,), 1) if args.quick else ((0, 1, 2), 3)
    laps = args.laps or laps
    oracle = args.reference == "scene"
    moves = [] if args.quick else list(MOVES[1:])
    jobs = ([(s, laps, True, 0.0, 0.0, oracle) for s in seeds] + [(s, laps, False, 0.0, 0.0, False) for s in seeds]
            + [(s, laps, True, share, dist, oracle) for share, dist in moves for s in seeds])
    result = dict(zip(jobs, run_all(jobs, args.workers), strict=True))
    on = [result[(s, laps, True, 0.0, 0.0, oracle)] for s in seeds]
    off = [result[(s, laps, False, 0.0, 0.0, False)] for s in seeds]
    moved = {(share, dist): [result[(s, laps, True, share, dist, oracle)] for s in seeds] for share, dist in moves}
    figures: dict[str, float] = {"oracle_reference": float(oracle)}
    merged_on = {"rows": [r for x in on for r in x["rows"]], "completed": sum(x["completed"] for x in on)}
    merged_off = {"rows": [r for x in off for r in x["rows"]], "completed": sum(x["completed"] for x in off)}
    figures.update(ate_figures(merged_on, laps))
    figures.update(ate_figures(merged_off, laps, "_odom"))
    figures["final_error_m"] = float(np.mean([ate_figures(x, laps)["final_error_m"] for x in on]))
    figures["final_error_m_odom"] = float(np.mean([ate_figures(x, laps)["final_error_m"] for x in off]))
    all_on = {"corrections": [c for x in on for c in x["corrections"]],
              "counts": {k: sum(x["counts"].get(k, 0) for x in on) for x in on for k in x["counts"]}}
    figures.update(registration_figures(all_on))
    figures["control_ms_median_on"] = percentile([c for x in on for c in x["control_ms"]], 50)
    figures["control_ms_median_off"] = percentile([c for x in off for c in x["control_ms"]], 50)
    figures["wall_s_on"] = float(sum(x["wall_s"] for x in on))
    figures["wall_s_off"] = float(sum(x["wall_s"] for x in off))
    if not args.quick:
        figures["false_corrections_pct_0_0"], figures["pulled_away_pct_0_0"] = correction_figures(on)
        figures["corrections_0_0"] = float(sum(accepted(x) for x in on))
        worst, worst_pulled = figures["false_corrections_pct_0_0"], figures["pulled_away_pct_0_0"]
        for (share, dist), runs in moved.items():
            key = f"false_corrections_pct_{int(share * 100)}_{int(round(dist * 100))}"
            pulled = key.replace("false_corrections_pct", "pulled_away_pct")
            figures[key], figures[pulled] = correction_figures(runs)
            worst_pulled = max(worst_pulled, figures[pulled])
            figures[key.replace("false_corrections_pct", "corrections")] = float(sum(accepted(x) for x in runs))
            figures[key.replace("false_corrections_pct", "ate_rmse_m")] = ate_figures(
                {"rows": [r for x in runs for r in x["rows"]], "completed": 0}, laps)["ate_rmse_m"]
            figures[key.replace("false_corrections_pct", "completed")] = float(sum(x["completed"] for x in runs))
            worst = max(worst, figures[key])
        figures["false_corrections_pct"] = worst
        figures["pulled_away_pct"] = worst_pulled
    figures["faulted_runs"] = float(sum(r["fault"] is not None for r in result.values()))
    units = {k: ("ms" if "_ms" in k else "deg" if "_deg" in k else "%" if "pct" in k else "s" if "wall_s" in k
                 else "m" if k.startswith(("ate", "final", "rpe")) else "") for k in figures}
    targets = {"faulted_runs": "== 0", "ate_rmse_m": "<= 0.05", "ate_max_m": "<= 0.15", "registration_ms_p95": "<= 50",
               "false_corrections_pct": "<= 1", "ate_rmse_lap3_m": "<= 1.2 x lap1"}
    faults = [f"{condition(*k[:1], *k[2:5])}: {r['fault']}" for k, r in result.items() if r["fault"] is not None]
    write_result(NAME, figures, units, targets, quick=args.quick, extra={"faults": faults})
    return figures


if __name__ == "__main__":
    main()
