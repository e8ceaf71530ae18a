"""Soak: a long closed loop and many run-control cycles, watching for collisions, crashes, faults and memory.

1. Lockstep: 30 simulated minutes (3 with `--quick`) of the two pick-up stops on the default scene, over
   and over, with the object map and CBF; every 10 s of sim time a box (not one the sequence works at) is
   moved to a random free spot, never onto or into the robot, nor onto a subtask's goal.
2. The bridge's HTTP API (real uvicorn on 127.0.0.1) against a live runtime on the embedded simulation:
   200 cycles (20 with `--quick`) of Start, Stop or E-stop, Reset. After each cycle: the resident memory once
   garbage is collected and the heap's free memory handed back (what is still in use, not what the allocator
   keeps), threads, child processes and GL contexts. Memory growth is the slope over whole sawtooth periods of
   cycles 100–200 (warm-up first fills caches and arenas); `--quick` cannot reach them and says so.

    python -m bench.soak [--quick] [--api-only] [--cycles N]

`--api-only` runs part 2 alone, `--lockstep-only` part 1 alone; `--localization` runs part 1 with the pose
localized (off by default, as the product's defaults); `--cycles` sets its count; the JSON keeps the RSS after
every cycle (`extra.api_rss_mb`) so a figure can be checked against the series it was fitted on.
"""

from __future__ import annotations

import argparse
import gc
import logging
import math
import multiprocessing
import os
import secrets
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import numpy as np
from rich.progress import Progress

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from app.runtime.native_memory import release_free_memory
from app.runtime.snapshot import RunState
from bench.report import bench_args, write_result
from core.params import LocalizationParams
from core.sim.world import SceneEditError
from core.types import MappedObject
from tasks.sequence_file import EXAMPLES_DIR, load_sequence
from tasks.validation import Obstacle, box_distance

log = logging.getLogger("bench.soak")

SEQUENCE = EXAMPLES_DIR / "two_pickups.yaml"
MOVE_EVERY_S = 10.0
MOVABLE = ("box_b", "box_c", "box_d", "box_e")
"""The default scene's boxes the sequence does not work at (box_a is picked from, the table placed on)."""
AREA = ((-1.0, 6.5), (-3.0, 3.0))
ROBOT_CLEAR_M = 1.6
"""A moved box's centre stays this far from the robot's base centre: the base's collision boxes reach 0.62 m
(half the diagonal of the 0.96 × 0.79 m body, `core/robot/collision_boxes.py`), a default box's half diagonal
0.42 m, and room to brake. The arm may still reach over a moved box: the controller keeps it clear."""
GOAL_CLEAR_M = 1.2
BOX_CLEAR_M = 0.9


def rss_mb() -> float:
    """Resident memory of this process (MB)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return math.nan


def collected_rss_mb() -> float:
    """Resident memory once garbage is collected and free heap memory handed back to the system (MB)."""
    gc.collect()
    release_free_memory()
    return rss_mb()


def gl_contexts() -> int:
    """Live GL contexts of this process (MuJoCo's, freed ones excluded)."""
    return sum(1 for o in gc.get_objects() if type(o).__name__ == "GLContext" and getattr(o, "_context", None))


def sawtooth_period(values: np.ndarray, max_lag: int | None = None) -> int:
    """The dominant period (samples) of a detrended series by autocorrelation; 1 when there is none (< 0.3)."""
    n = len(values)
    if n < 8:
        return 1
    x = np.arange(n)
    resid = values - np.polyval(np.polyfit(x, values, 1), x)
    if not np.any(resid):
        return 1
    lags = range(2, (max_lag or n // 2) + 1)
    corr = [float(np.corrcoef(resid[:-lag], resid[lag:])[0, 1]) for lag in lags]
    best = int(np.nanargmax(corr)) if corr else -1
    return list(lags)[best] if best >= 0 and corr[best] >= 0.3 else 1


def growth_over_periods(values: np.ndarray) -> tuple[float, int, int]:
    """Slope per sample fitted over the longest whole number of sawtooth periods ending at the last sample;
    (slope, period, samples used)."""
    period = sawtooth_period(values)
    used = (len(values) - 1) // period * period + 1
    if used < 3:
        return math.nan, period, used
    tail = values[-used:]
    return float(np.polyfit(np.arange(used), tail, 1)[0]), period, used


def growth_mb_per_min(samples: list[tuple[float, float]], warmup: float = 0.2) -> float:
    """Slope of RSS over wall time (MB/min) after the first `warmup` fraction of the samples (the warm-up:
    allocator arenas, caches and the first solver and map buffers fill once)."""
    rows = np.array(samples[int(len(samples) * warmup):])
    if len(rows) < 3 or rows[-1, 0] - rows[0, 0] < 1.0:
        return math.nan
    return float(np.polyfit(rows[:, 0] / 60.0, rows[:, 1], 1)[0])


@dataclass
class Tally:
    collisions: int = 0
    crashes: int = 0
    faults: list[str] = field(default_factory=list)
    laps: int = 0
    subtasks_done: int = 0
    subtasks_failed: int = 0
    box_moves: int = 0
    failures: list[str] = field(default_factory=list)
    traces: list[str] = field(default_factory=list)
    """One line per failed subtask: the poses, the localization's health, the mapped objects and unknown space
    nearest the base (`failure_trace`), to trace a failure without running again."""
    rss: list[tuple[float, float]] = field(default_factory=list)


TRAIL_S = 600.0
"""How far back the pose trail reaches (s of sim time): a failure's nearest mapped object is traced to the base's
poses when it was created, if that was this recent."""


class PoseTrail:
    """The base's estimated and true pose at every control step over the last `TRAIL_S` (a ring, ~0.1 ms a step):
    where the robot thought it stood, and stood, when a mapped object was created."""

    def __init__(self, control_rate_hz: float = 10.0) -> None:
        self.rows: deque[tuple[float, np.ndarray, np.ndarray | None]] = deque(maxlen=int(TRAIL_S * control_rate_hz))

    def record(self, rt: Runtime) -> None:
        loop = rt.closed_loop
        true = loop.base_true
        self.rows.append((rt.time, rt.state.q[:3].copy(), None if true is None else true.copy()))

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray | None] | None:
        """(estimate, truth) at the row nearest time t; None if t is outside the trail."""
        if not self.rows or not np.isfinite(t) or t < self.rows[0][0] - 0.2 or t > self.rows[-1][0] + 0.2:
            return None
        _, est, true = min(self.rows, key=lambda row: abs(row[0] - t))
        return est, true


def _pose(xyyaw: np.ndarray | None) -> str:
    if xyyaw is None:
        return "?"
    return f"({xyyaw[0]:.2f}, {xyyaw[1]:.2f}, {math.degrees(xyyaw[2]):.0f} deg)"


def _footprint_distance(xy: np.ndarray, obj: MappedObject) -> float:
    """Distance (m) in x-y from a point to an object's box footprint (0 inside it; the target checks' box_distance)."""
    yaw = math.atan2(obj.pose[1, 0], obj.pose[0, 0])
    box = Obstacle(str(obj.id), tuple(obj.pose[:3, 3]), tuple(obj.extent), yaw)
    return max(float(box_distance(box, np.asarray(xy, float)[:2])), 0.0)


def failure_trace(rt: Runtime, trail: PoseTrail, n_objects: int = 3, unknown_within_m: float = 1.5) -> str:
    """One line to trace a failed subtask: the base's true and estimated pose and the localization's health, the
    `n_objects` mapped objects nearest the estimated base (id, centre, yaw, extent, E[v], observations, created
    when and by which camera with the base's estimated and true pose then, last seen) and the unknown floor cells
    within `unknown_within_m` (the planner counts them as obstacles)."""
    loop = rt.closed_loop
    est = rt.state.q[:3]
    health = loop.health(rt.time)
    loc = ("off" if health is None else
           f"3sigma {3 * health.sigma_xy_m * 100:.1f} cm, accepted {health.accepted}, rejected {health.rejected}, "
           f"degenerate {health.degenerate}, since accepted {health.since_accepted_s:.1f} s"
           + (f", untrusted: {health.untrusted}" if health.untrusted else ""))
    with loop.using_map() as world_map:
        snap = world_map.snapshot()
    near = sorted(snap.objects, key=lambda o: _footprint_distance(est[:2], o))[:n_objects]
    parts = []
    for o in near:
        yaw = math.degrees(math.atan2(o.pose[1, 0], o.pose[0, 0]))
        then = trail.at(o.first_seen_t)
        created = (f"created t {o.first_seen_t:.1f} by {o.first_camera or '?'}"
                   + (f" (base est {_pose(then[0])}, true {_pose(then[1])})" if then else ""))
        parts.append(f"#{o.id} at ({o.pose[0, 3]:.2f}, {o.pose[1, 3]:.2f}, {o.pose[2, 3]:.2f}) yaw {yaw:.0f} deg "
                     f"extent ({o.extent[0]:.2f}, {o.extent[1]:.2f}, {o.extent[2]:.2f}), "
                     f"{_footprint_distance(est[:2], o):.2f} m from base, E[v] {o.consistency:.2f}, "
                     f"obs {o.observations}, {created}, last seen t {o.last_seen_t:.1f}")
    edf = rt.last_edf
    space = edf.unknown if edf is not None else None
    unknown = "none"
    if space is not None and len(space.centres):
        d = np.linalg.norm(space.centres - est[:2], axis=1)
        close = d < unknown_within_m
        if close.any():
            i = int(np.argmin(d))
            unknown = (f"{int(close.sum())} cells within {unknown_within_m} m, nearest ({space.centres[i, 0]:.2f}, "
                       f"{space.centres[i, 1]:.2f}) {d[i]:.2f} m")
    return (f"true base {_pose(loop.base_true)}, estimate {_pose(est)}; localization {loc}; "
            f"nearest mapped: {'; '.join(parts) or 'none'}; unknown floor: {unknown}")


class BoxMover:
    """The `on_control` callback: every `MOVE_EVERY_S` of sim time, one movable box to a random free spot (and the
    pose trail, every step)."""

    def __init__(self, tally: Tally, goals: np.ndarray, seed: int = 0) -> None:
        self.tally, self.goals = tally, goals
        self.rng = np.random.default_rng(seed)
        self.next_t = MOVE_EVERY_S
        self.trail = PoseTrail()

    def __call__(self, rt: Runtime) -> None:
        self.trail.record(rt)
        if rt.time + 1e-9 < self.next_t:
            return
        self.next_t = rt.time + MOVE_EVERY_S
        self.tally.rss.append((time.monotonic(), rss_mb()))
        boxes = {b.id: b for b in rt.world.boxes()}
        box_id = str(self.rng.choice([b for b in MOVABLE if b in boxes]))
        others = np.array([b.position[:2] for b in boxes.values() if b.id != box_id])
        for _ in range(200):
            xy = np.array([self.rng.uniform(*AREA[0]), self.rng.uniform(*AREA[1])])
            if (np.hypot(*(xy - rt.state.q[:2])) < ROBOT_CLEAR_M
                    or np.min(np.linalg.norm(self.goals - xy, axis=1)) < GOAL_CLEAR_M
                    or (len(others) and np.min(np.linalg.norm(others - xy, axis=1)) < BOX_CLEAR_M)):
                continue
            try:
                rt.move_box(box_id, (float(xy[0]), float(xy[1]), boxes[box_id].size[2] / 2),
                            float(self.rng.uniform(-math.pi, math.pi)))
            except SceneEditError:
                continue
            self.tally.box_moves += 1
            return


def _goals(rt: Runtime) -> np.ndarray:
    """Base goals and the points under EE goals of the sequence (x, y)."""
    pts = []
    for sub in rt.sequence.subtasks:
        goal = sub.goal()
        pts.append(goal.position[:2] if hasattr(goal, "position") else (goal.x, goal.y))
    return np.array(pts, dtype=float)


def _scene_near_robot(rt: Runtime, radius_m: float = 2.5) -> str:
    """Where the robot stopped and the boxes around it (to tell a box moved into the way from a controller
    that got stuck)."""
    x, y, yaw = rt.state.q[:3]
    near = [f"{b.id} ({b.position[0]:.2f}, {b.position[1]:.2f})" for b in rt.world.boxes()
            if np.hypot(b.position[0] - x, b.position[1] - y) < radius_m]
    return f"robot at ({x:.2f}, {y:.2f}, {math.degrees(yaw):.0f} deg), boxes within {radius_m} m: {', '.join(near)}"


def _end_lap(rt: Runtime, tally: Tally, trail: PoseTrail) -> None:
    progress = rt.sequencer.progress
    tally.subtasks_done += sum(p.outcome.value == "done" for p in progress)
    failed = [p for p in progress if p.outcome.value == "failed"]
    tally.subtasks_failed += len(failed)
    if failed:
        tally.failures += [f"t = {rt.time:.0f} s: {p.name}: {p.message}; {_scene_near_robot(rt)}" for p in failed]
        trace = f"t = {rt.time:.1f} s: {failed[0].name}: {failed[0].message}; {failure_trace(rt, trail)}"
        tally.traces.append(trace)
        log.warning("failed subtask: %s", trace)
    tally.laps += 1


def lockstep_soak(sim_minutes: float, seed: int = 0, localization: bool = False) -> Tally:
    """The looping sequence with boxes moving, in simulated time; collisions, crashes, faults, memory. With
    `localization` the pose is the localizer's (`LocalizationParams.enabled`), else the drifting odometry."""
    tally = Tally()
    config = RuntimeConfig(map_kind="object", localization=LocalizationParams(enabled=localization))
    rt = Runtime(config, sequence=load_sequence(SEQUENCE))
    mover = BoxMover(tally, _goals(rt), seed)
    total = sim_minutes * 60.0
    done = 0.0
    with Progress() as progress:
        task = progress.add_task("lockstep soak", total=total)
        while done < total - 1e-6:
            t_start, crashed = rt.time, False
            try:
                rt.run_lockstep(total - done, on_control=mover)
            except Exception:
                log.exception("run_lockstep crashed")
                tally.crashes, crashed = tally.crashes + 1, True
            done += max(rt.time - t_start, 0.01)
            progress.update(task, completed=done)
            if rt.fault is not None or crashed:
                tally.faults += [rt.fault] if rt.fault else []
                tally.collisions += len(rt.world.collisions)
                rt.reset()
                mover.next_t = rt.time + MOVE_EVERY_S
            elif rt.run_state in (RunState.FINISHED, RunState.FAILED):
                _end_lap(rt, tally, mover.trail)
    tally.collisions += len(rt.world.collisions)
    if rt.run_state == RunState.RUNNING:  # the lap under way when time ran out
        _end_lap(rt, tally, mover.trail)
        tally.laps -= 1
    tally.rss.append((time.monotonic(), rss_mb()))
    return tally


STEADY_FROM_CYCLE = 100
"""Memory growth is fitted from this cycle on: the floor of the sawtooth rises over the first ~100 cycles
(warm-up: caches, arenas, the first solver and map buffers) and is flat after that (issue 32's 200-cycle run)."""
MIN_STEADY_CYCLES = 50
"""At least this many cycles past `STEADY_FROM_CYCLE` to say anything about growth."""


@dataclass
class ApiTally:
    cycles: int = 0
    failures: list[str] = field(default_factory=list)
    faults: list[str] = field(default_factory=list)
    """The fault of each cycle that ended in one."""
    rss: list[tuple[float, float]] = field(default_factory=list)
    """(monotonic s, RSS MB after a collection: `collected_rss_mb`) after each cycle, the first row before any."""
    threads: list[int] = field(default_factory=list)
    """Threads of this process after each cycle, the first entry before any."""
    children: list[int] = field(default_factory=list)
    """Child processes (the map worker) after each cycle, the first entry before any."""
    contexts: list[int] = field(default_factory=list)
    """Live GL contexts before any cycle, after the first and after the last (a scan of every object holds the
    GIL for seconds on a loaded machine: done every cycle, it stalled the live loops)."""
    processes_after: int = 0
    """Child processes left once the runtime has shut down."""

    def record(self, count_contexts: bool = False) -> None:
        self.rss.append((time.monotonic(), collected_rss_mb()))
        self.threads.append(threading.active_count())
        self.children.append(len(multiprocessing.active_children()))
        if count_contexts:
            self.contexts.append(gl_contexts())

    def growth_note(self) -> str:
        steady = self.cycles - STEADY_FROM_CYCLE
        if steady < MIN_STEADY_CYCLES:
            return (f"memory growth cannot be told from {self.cycles} cycles: it is fitted over cycles "
                    f"{STEADY_FROM_CYCLE}–{STEADY_FROM_CYCLE + 100} (run without --quick)")
        _, period, used = growth_over_periods(np.array([r for _, r in self.rss[STEADY_FROM_CYCLE:]]))
        return (f"memory growth fitted over cycles {self.cycles - used + 1}–{self.cycles}: {(used - 1) // period} "
                f"whole periods of {period} cycles")

    def figures(self) -> dict[str, float]:
        """Growth over whole sawtooth periods from cycle `STEADY_FROM_CYCLE` on (NaN with fewer than
        `MIN_STEADY_CYCLES` there); leaks of threads, child processes and GL contexts since the first cycle (the
        first Start makes what every later cycle reuses)."""
        rss = np.array([r for _, r in self.rss])
        steady = rss[STEADY_FROM_CYCLE:] if self.cycles - STEADY_FROM_CYCLE >= MIN_STEADY_CYCLES else np.zeros(0)
        growth, period, _ = growth_over_periods(steady) if len(steady) else (math.nan, 0, 0)
        first = min(1, len(rss) - 1)
        return {"api_cycles": float(self.cycles), "api_failures": float(len(self.failures)),
                "api_faults": float(len(self.faults)),
                "api_rss_growth_mb_per_min": growth_mb_per_min(self.rss, warmup=0.5),
                "api_rss_growth_mb_per_cycle": growth, "api_rss_sawtooth_cycles": float(period),
                "api_rss_warmup_mb": (float(rss[STEADY_FROM_CYCLE] - rss[0]) if len(rss) > STEADY_FROM_CYCLE
                                      else math.nan),
                "api_rss_end_mb": float(rss[-1]) if len(rss) else math.nan,
                "api_threads_leaked": float(self.threads[-1] - self.threads[first]) if self.cycles else math.nan,
                "api_threads_warmup": float(self.threads[first] - self.threads[0]) if self.cycles else math.nan,
                "api_child_processes_leaked": (float(self.children[-1] - self.children[first]) if self.cycles
                                               else math.nan),
                "api_gl_contexts_leaked": float(self.contexts[-1] - self.contexts[first]) if self.cycles else math.nan,
                "api_child_processes": float(self.processes_after)}


def _expect(response: httpx.Response, run_state: str, tally: ApiTally, what: str) -> None:
    if response.status_code != 200:
        tally.failures.append(f"{what}: HTTP {response.status_code} {response.text[:200]}")
    elif response.json().get("run_state") != run_state:
        tally.failures.append(f"{what}: run_state {response.json().get('run_state')!r}, expected {run_state!r}")


def api_cycles(n: int, pause_s: float = 0.3) -> ApiTally:
    """`n` cycles of Start, Stop (even) or E-stop (odd), Reset through the bridge's operator API."""
    tally = ApiTally()
    with tempfile.TemporaryDirectory() as tmp:
        bridge = BridgeServer(port=0, token=secrets.token_urlsafe(24), token_file=Path(tmp) / "token")
        bridge.start()
        runtime = Runtime(RuntimeConfig())
        bridge.attach(runtime)
        runtime.start_live()
        tally.record(count_contexts=True)
        headers = {"Authorization": f"Bearer {bridge.token}"}
        try:
            with httpx.Client(base_url=bridge.url, headers=headers, timeout=60.0) as api, Progress() as progress:
                task = progress.add_task("API cycles", total=n)
                for i in range(n):
                    _expect(api.post("/api/run/start"), "running", tally, f"cycle {i} start")
                    time.sleep(pause_s)
                    halt = "stop" if i % 2 == 0 else "emergency-stop"
                    _expect(api.post(f"/api/run/{halt}"), "idle" if halt == "stop" else "emergency_stop", tally,
                            f"cycle {i} {halt}")
                    fault = api.get("/api/state").json().get("fault")
                    if fault:
                        tally.faults.append(fault)
                    _expect(api.post("/api/run/reset"), "idle", tally, f"cycle {i} reset")
                    tally.cycles += 1
                    tally.record(count_contexts=i in (0, n - 1))
                    progress.update(task, completed=i + 1)
        finally:
            runtime.shutdown()
            bridge.stop()
    deadline = time.monotonic() + 30.0  # the worker ends at shutdown; a loaded machine reaps it late
    while multiprocessing.active_children() and time.monotonic() < deadline:
        time.sleep(0.2)
    tally.processes_after = len(multiprocessing.active_children())
    return tally


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--api-only", action="store_true", help="only the operator API's cycles (part 2)")
    parser.add_argument("--lockstep-only", action="store_true", help="only the lockstep soak (part 1)")
    parser.add_argument("--localization", action="store_true",
                        help="part 1 with localization on (default: the odometry alone, as the defaults run)")
    parser.add_argument("--cycles", type=int, default=None,
                        help=f"API cycles (default {STEADY_FROM_CYCLE + 100}; 20 with --quick)")


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0], argv, _options)
    sim_minutes, n_cycles = (3.0, 20) if args.quick else (30.0, STEADY_FROM_CYCLE + 100)
    n_cycles = args.cycles or n_cycles
    wall0, cpu0, load0 = time.monotonic(), time.process_time(), os.getloadavg()
    figures: dict[str, float] = {}
    soak = None
    if not args.api_only:
        soak = lockstep_soak(sim_minutes, localization=args.localization)
        figures |= {
            "collisions": float(soak.collisions),
            "crashes": float(soak.crashes),
            "subtasks_failed": float(soak.subtasks_failed),
            "subtasks_done": float(soak.subtasks_done),
            "laps": float(soak.laps),
            "box_moves": float(soak.box_moves),
            "sim_minutes": sim_minutes,
            "localization": float(args.localization),
            "lockstep_rtf": sim_minutes * 60.0 / (time.monotonic() - wall0),
            "rss_growth_mb_per_min": growth_mb_per_min(soak.rss),
            "rss_end_mb": soak.rss[-1][1],
        }
    cycles = None if args.lockstep_only else api_cycles(n_cycles)
    lockstep_faults = soak.faults if soak is not None else []
    api_faults = cycles.faults if cycles is not None else []
    figures |= {
        "faults": float(len(lockstep_faults) + len(api_faults)),
        **(cycles.figures() if cycles is not None else {}),
        "cpu_s": time.process_time() - cpu0,
        "wall_s": time.monotonic() - wall0,
        "load_average_1min_start": load0[0],
    }
    units = {"rss_growth_mb_per_min": "MB/min", "api_rss_growth_mb_per_min": "MB/min", "sim_minutes": "min",
             "api_rss_growth_mb_per_cycle": "MB", "api_rss_warmup_mb": "MB", "api_rss_end_mb": "MB",
             "api_rss_sawtooth_cycles": "cycles",
             "lockstep_rtf": "x", "rss_end_mb": "MB", "cpu_s": "s", "wall_s": "s"}
    targets = {"collisions": "== 0", "crashes": "== 0", "faults": "== 0", "rss_growth_mb_per_min": "<= 1",
               "subtasks_failed": "== 0", "api_failures": "== 0", "api_faults": "== 0",
               "api_rss_growth_mb_per_cycle": "<= 0.1", "api_threads_leaked": "== 0",
               "api_child_processes_leaked": "== 0", "api_gl_contexts_leaked": "== 0", "api_child_processes": "== 0"}
    api = ({"api_failures": cycles.failures[:20], "api_rss_growth_note": cycles.growth_note(),
            "api_rss_mb": [round(r, 2) for _, r in cycles.rss]} if cycles is not None else {})
    if cycles is not None:
        print(cycles.growth_note())
    write_result("soak", figures, units, {k: v for k, v in targets.items() if k in figures}, quick=args.quick,
                 extra={"faults": lockstep_faults + api_faults,
                        "subtask_failures": soak.failures[:50] if soak is not None else [],
                        "failure_traces": soak.traces[:50] if soak is not None else [], **api})


if __name__ == "__main__":
    main()
