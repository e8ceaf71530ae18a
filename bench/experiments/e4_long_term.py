"""E4: long-term operation: three laps of a circular aisle, two pick-up stops a lap, boxes rearranged.

    python -m bench.experiments.e4_long_term [--quick] [--workers N] [--ray ADDRESS]

Scene: `aisle_scene(aisle_m=2.6)`, a ring corridor around an island of shelf rows (0.8 m tall), plus
`LOOSE` boxes of 0.6 m standing in the corridor against a wall (2.0 m stay free: the base needs
1.6 m, its sphere and delta on both sides). The corridor is wider than the default 1.9 m aisle so a
box in it can be passed at all: in the 1.9 m aisle any 0.6 m box closes it (1.3 m left).

Task (built here like `tasks/examples/aisle_laps.yaml`): per lap, drive to stop A (south straight),
bring the hand above the island shelf and dwell 2 s (pick), drive round the east end to stop B
(north straight), pick over the island there, drive round the west end back to the start; 3 laps,
15 subtasks. A failed subtask is skipped (as an operator would) and counted; the run goes on.

Rearrangement: at the start of laps 2 and 3 (in the one-lap quick run: after pick A) every loose
box moves to another of the `SPOTS` (seeded), each one only at a moment when neither its old nor its
new place is in either camera's view: the robot comes back to changes it did not see. Maps: the
object-level map (POCD) and the voxel-level baseline, same scene, same moves; the ground truth as
the reference.

Measured per lap: subtasks completed, collisions, time, driven path, phantoms at the lap's end (old
places of moved boxes the map still holds as occupied) and the boxes the robot has not yet seen
moved. The full run also runs the shipped `aisle_laps.yaml` as authored (default 1.9 m aisle, no
loose boxes) with the object map and the ground truth, to report how the example itself fares.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from app.runtime import Runtime
from app.runtime.snapshot import RunState
from bench.experiments.measures import box_in_view, phantoms, run_metrics, solver_figures
from bench.experiments.report_files import (
    draw_boxes,
    finish_experiment,
    md_table,
    save_figure,
    write_markdown,
)
from bench.experiments.trials import Trial, experiment_args, quiet_logs, runtime_config, trial_results
from core.scene import PAPER_BOX_M, Box, Scene, aisle_scene
from tasks import BasePose, BaseSubtask, EEPose, EESubtask, TaskSequence, Tolerance
from tasks.sequence_file import EXAMPLES_DIR, load_sequence
from tasks.sequencer import Outcome

log = logging.getLogger(__name__)

NAME = "e4_long_term"
AISLE_M = 2.6
LAPS = 3
ISLAND_X, ISLAND_Y = 3.0, 1.5
"""Half length and half width of the island (its rows' outer faces; `aisle_scene` defaults)."""
MID_X, MID_Y = ISLAND_X + AISLE_M / 2, ISLAND_Y + AISLE_M / 2
"""Centre lines of the east/west and the south/north straights."""
HALF = PAPER_BOX_M / 2
SPOTS: tuple[tuple[float, float], ...] = (
    (2.3, -(ISLAND_Y + HALF)), (-0.6, -(ISLAND_Y + AISLE_M - HALF)),
    (ISLAND_X + AISLE_M - HALF, 0.9), (ISLAND_X + HALF, -0.9),
    (2.0, ISLAND_Y + AISLE_M - HALF), (-2.3, ISLAND_Y + HALF),
    (-(ISLAND_X + AISLE_M - HALF), 0.9), (-(ISLAND_X + HALF), -0.9))
"""Places for loose boxes, against a wall, away from the stops and the start. Two spots of one straight
are far enough apart (≥ 1.6 m between the boxes) that the base passes between them whichever are taken."""
PICK_INSET_M = 0.1
"""The hand's pick target is this far in over the island's edge, as in the shipped example. At 0.2 m the
base and upper-arm spheres end 5 cm from their delta boundary at the pick; the object map's EDF is up
to one EDF voxel (0.1 m) conservative there and the pick timed out 6 cm short."""
LOOSE = 4
SEED = 0
PAPER = "three laps of a circular aisle with two pick-up stops per lap while boxes are rearranged (no numbers)"


def lap_sequence(laps: int = LAPS) -> TaskSequence:
    """`laps` × [to stop A, pick A, to stop B (round the east end), pick B, back (round the west end)]."""
    tol_base, tol_ee = Tolerance(position_m=0.15, orientation_deg=15.0), Tolerance(position_m=0.03,
                                                                                   orientation_deg=5.0)
    subtasks = []
    for lap in range(1, laps + 1):
        subtasks += [
            BaseSubtask(name=f"lap {lap}: to stop A", target=BasePose(x=0.75, y=-MID_Y, yaw_deg=0.0),
                        tolerance=tol_base, timeout_s=60.0),
            EESubtask(name=f"lap {lap}: pick at stop A", target=EEPose(position=(0.75, -(ISLAND_Y - PICK_INSET_M), 1.5),
                                                                      rpy_deg=(0.0, 90.0, 0.0)),
                      tolerance=tol_ee, timeout_s=30.0, dwell_s=2.0),
            BaseSubtask(name=f"lap {lap}: to stop B", target=BasePose(x=-0.75, y=MID_Y, yaw_deg=180.0),
                        waypoints=[BasePose(x=MID_X, y=-MID_Y), BasePose(x=MID_X, y=MID_Y)], tolerance=tol_base,
                        timeout_s=90.0),
            EESubtask(name=f"lap {lap}: pick at stop B", target=EEPose(position=(-0.75, ISLAND_Y - PICK_INSET_M, 1.5),
                                                                      rpy_deg=(0.0, 90.0, 180.0)),
                      tolerance=tol_ee, timeout_s=30.0, dwell_s=2.0),
            BaseSubtask(name=f"lap {lap}: back to start", target=BasePose(x=-1.5, y=-MID_Y, yaw_deg=0.0),
                        waypoints=[BasePose(x=-MID_X, y=MID_Y), BasePose(x=-MID_X, y=-MID_Y)], tolerance=tol_base,
                        timeout_s=90.0)]
    return TaskSequence(name="aisle laps with loose boxes", subtasks=subtasks)


def change_points(laps: int) -> tuple[int, ...]:
    """Subtasks at which the boxes are rearranged: the start of laps 2, 3, …; with one lap, after pick A
    (the robot then heads east, away from most spots)."""
    return tuple(5 * k for k in range(1, laps)) if laps > 1 else (2,)


def layouts(seed: int, n: int) -> list[tuple[int, ...]]:
    """Spot index of every loose box in each of `n` layouts; each box changes spot every time (seeded)."""
    rng = np.random.default_rng(seed)
    out = [tuple(range(0, 2 * LOOSE, 2))]
    while len(out) < n:
        cand = tuple(int(i) for i in rng.permutation(len(SPOTS))[:LOOSE])
        if all(a != b for a, b in zip(cand, out[-1], strict=True)):
            out.append(cand)
    return out


def _box(i: int, spot: int) -> Box:
    x, y = SPOTS[spot]
    return Box(f"loose_{i}", (x, y, PAPER_BOX_M / 2))


def scene(first: tuple[int, ...]) -> Scene:
    base = aisle_scene(aisle_m=AISLE_M)
    loose = tuple(_box(i, s) for i, s in enumerate(first))
    return Scene(base.boxes + loose, robot_start=(-1.5, -MID_Y, 0.0), name="aisle with loose boxes",
                 metadata=dict(base.metadata))


@dataclass
class _Laps:
    """`on_control`: lap bookkeeping, rearrangements out of view, phantoms at each lap's end."""

    layouts: list[tuple[int, ...]]
    change_at: tuple[int, ...]
    """Subtask indices at which the next layout begins (one fewer than layouts)."""
    per_lap: int = 5
    stage: int = 0
    pending: dict[int, int] = field(default_factory=dict)
    """Box index → spot it still has to move to (waiting for both places to be out of view)."""
    moved_from: list[Box] = field(default_factory=list)
    lap_end_t: list[float] = field(default_factory=list)
    lap_phantoms: list[int] = field(default_factory=list)
    unseen_moves: list[int] = field(default_factory=list)
    done_offset: int = 0

    def __call__(self, rt: Runtime) -> None:
        index = self.done_offset + rt.sequencer.index
        if index >= (len(self.lap_end_t) + 1) * self.per_lap:
            self._end_lap(rt)
        stage = sum(index >= c for c in self.change_at)
        if stage > self.stage:
            self.stage = stage
            self.pending = dict(enumerate(self.layouts[stage]))
        self._move_unseen(rt)

    def _end_lap(self, rt: Runtime) -> None:
        self.lap_end_t.append(rt.time)
        self.lap_phantoms.append(phantoms(rt.map.occupied_points(), tuple(self.moved_from), rt.world.boxes()).count)
        self.unseen_moves.append(len(self.pending))

    def _move_unseen(self, rt: Runtime) -> None:
        frames = list(rt.latest_frames.values())
        for i, spot in list(self.pending.items()):
            old, new = rt.world.box(f"loose_{i}"), _box(i, spot)
            if box_in_view(frames, old) or box_in_view(frames, new):
                continue
            rt.move_box(old.id, new.position)
            self.moved_from = [b for b in self.moved_from if math.dist(b.position, new.position) > 0.3] + [old]
            del self.pending[i]


def run_sequence(rt: Runtime, sequence: TaskSequence, max_s: float, on_control) -> list[dict]:
    """Run every subtask; a failed one is recorded and skipped (the rest restarts from the next)."""
    outcomes: list[dict] = []
    remaining = list(sequence.subtasks)
    t_end = rt.time + max_s
    while remaining and rt.time < t_end:
        rt.set_sequence(TaskSequence(name=sequence.name, subtasks=remaining), scene_may_change=True)  # boxes move here
        rt.run_lockstep(t_end - rt.time, on_control=on_control)
        progress = rt.sequencer.progress
        outcomes += [{"name": p.name, "outcome": p.outcome.value, "elapsed_s": p.elapsed_s, "message": p.message}
                     for p in progress if p.outcome in (Outcome.DONE, Outcome.FAILED)]
        done = sum(p.outcome in (Outcome.DONE, Outcome.FAILED) for p in progress)
        remaining = remaining[done:]
        if rt.run_state != RunState.FAILED:
            break
        if isinstance(on_control, _Laps):
            on_control.done_offset += done
    return outcomes + [not_reached(s.name, rt) for s in remaining]


def not_reached(name: str, rt: Runtime) -> dict:
    """The outcome of a subtask the run never reached: it faulted, stopped or ran out of time before it, with why."""
    why = f"the run ended {rt.run_state.value}" if rt.run_state != RunState.RUNNING else "out of the run's time"
    fault = f": {rt.fault}" if rt.fault else ""
    return {"name": name, "outcome": "not_reached", "elapsed_s": 0.0, "message": f"not reached: {why} at "
            f"t = {rt.time:.1f} s{fault}"}


def trial(params: dict) -> dict:
    """The laps with rearranged loose boxes, or the shipped example as authored (`params['part']`)."""
    if params["part"] == "authored":
        seq = load_sequence(EXAMPLES_DIR / "aisle_laps.yaml")
        laps, sc = _Laps([()], ()), aisle_scene()
    else:
        seq = lap_sequence(params["laps"])
        changes = change_points(params["laps"])
        plan = layouts(SEED, len(changes) + 1)
        laps, sc = _Laps(plan, changes), scene(plan[0])
    rt = Runtime(runtime_config(map_kind=params["map"], seed=SEED), scene=sc, sequence=seq)
    outcomes = run_sequence(rt, seq, params["laps"] * 150.0, laps)
    if len(laps.lap_end_t) < params["laps"]:
        laps._end_lap(rt)
    metrics = run_metrics(RunState.FINISHED if all(o["outcome"] == "done" for o in outcomes)
                          and len(outcomes) == len(seq.subtasks) else RunState.FAILED, rt.log, rt.world.collisions,
                          rt.controller.counts)
    return {**metrics, "subtasks": len(seq.subtasks), "completed": sum(o["outcome"] == "done" for o in outcomes),
            "outcomes": outcomes, "per_lap": _per_lap(rt, laps, outcomes), "path_xy": _decimated_path(rt),
            "final_boxes": [[b.id, *b.position[:2], b.size[0], b.size[1], b.yaw] for b in rt.world.boxes()]}


def _per_lap(rt: Runtime, laps: _Laps, outcomes: list[dict]) -> list[dict]:
    t = np.array(rt.log.t)
    xy = np.array([q[:2] for q in rt.log.q])
    rows, t0 = [], t[0] if len(t) else 0.0
    for k, t1 in enumerate(laps.lap_end_t):
        sel = (t >= t0) & (t <= t1)
        lap_out = outcomes[k * laps.per_lap:(k + 1) * laps.per_lap]
        contacts = [e for e in rt.world.collisions if t0 <= e.t <= t1]
        rows.append({"lap": k + 1, "completed": sum(o["outcome"] == "done" for o in lap_out),
                     "failed": [o["name"] for o in lap_out if o["outcome"] != "done"], "time_s": t1 - t0,
                     "path_m": float(np.linalg.norm(np.diff(xy[sel], axis=0), axis=1).sum()) if sel.sum() > 1 else 0.0,
                     "collision_events": len(contacts), "phantoms": laps.lap_phantoms[k],
                     "moves_not_done": laps.unseen_moves[k]})
        t0 = t1
    return rows


def _decimated_path(rt: Runtime) -> list[list[float]]:
    return [[float(q[0]), float(q[1])] for q in rt.log.q[::5]]


def summarise(results: list[dict]) -> dict[str, float]:
    figures: dict[str, float] = {}
    for r in results:
        if "error" in r:
            continue
        key = f"{r['part']}_{r['map']}"
        figures[f"{key}_completed"] = float(r["completed"])
        figures[f"{key}_subtasks"] = float(r["subtasks"])
        figures[f"{key}_collision_events"] = float(r["collision_events"])
        figures[f"{key}_min_clearance_m"] = r["min_clearance_m"]
        figures[f"{key}_duration_s"] = r["duration_s"]
        for lap in r["per_lap"]:
            figures[f"{key}_lap{lap['lap']}_phantoms"] = float(lap["phantoms"])
            figures[f"{key}_lap{lap['lap']}_completed"] = float(lap["completed"])
            figures[f"{key}_lap{lap['lap']}_time_s"] = lap["time_s"]
    return figures | solver_figures(results)


def figures_png(results: list[dict], out_dir: Path) -> list[str]:
    """Driven paths over the final scene, and phantoms and completed subtasks per lap."""
    names = []
    laps_rows = [r for r in results if r["part"] == "laps" and "error" not in r]
    if not laps_rows:
        return names
    fig, axes = plt.subplots(1, len(laps_rows), figsize=(6 * len(laps_rows), 5), squeeze=False)
    for ax, r in zip(axes[0], laps_rows, strict=True):
        draw_boxes(ax, tuple(Box(b[0], (b[1], b[2], 0.0), (b[3], b[4], 1.0), b[5]) for b in r["final_boxes"]))
        for spot in SPOTS:
            ax.plot(*spot, "+", color="grey")
        p = np.array(r["path_xy"])
        ax.plot(p[:, 0], p[:, 1], "-", lw=0.8)
        ax.set_aspect("equal")
        ax.set_title(f"{r['map']}: {r['completed']}/{r['subtasks']} subtasks")
    names.append(save_figure(fig, out_dir, "paths"))

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for j, r in enumerate(laps_rows):
        laps = [lap["lap"] for lap in r["per_lap"]]
        x = np.array(laps) + (j - (len(laps_rows) - 1) / 2) * 0.25
        axes[0].bar(x, [lap["phantoms"] for lap in r["per_lap"]], 0.25, label=r["map"])
        axes[1].bar(x, [lap["completed"] for lap in r["per_lap"]], 0.25, label=r["map"])
    axes[0].set_ylabel("phantom boxes at the lap's end")
    axes[1].set_ylabel("subtasks completed (of 5)")
    for ax in axes:
        ax.set_xlabel("lap")
        ax.legend()
    names.append(save_figure(fig, out_dir, "per_lap"))
    return names


def report(results: list[dict], pngs: list[str], out_dir: Path, quick: bool) -> None:
    ok = [r for r in results if "error" not in r]
    overall = md_table(["run", "map", "subtasks completed", "collision events", "min clearance (m)", "time (s)",
                        "path (m)"],
                       [[r["part"], r["map"], f"{r['completed']}/{r['subtasks']}", r["collision_events"],
                         r["min_clearance_m"], r["duration_s"], r["path_length_m"]] for r in ok])
    laps = md_table(["run", "map", "lap", "completed (of 5)", "failed subtasks", "collision events", "time (s)",
                     "path (m)", "phantoms at lap end", "moves still waiting"],
                    [[r["part"], r["map"], lap["lap"], lap["completed"], ", ".join(lap["failed"]) or "–",
                      lap["collision_events"], lap["time_s"], lap["path_m"], lap["phantoms"], lap["moves_not_done"]]
                     for r in ok for lap in r["per_lap"]])
    failed_rows = [[r["part"], r["map"], o["name"], o["elapsed_s"], o["message"]]
                   for r in ok for o in r["outcomes"] if o["outcome"] != "done"]
    failed = md_table(["run", "map", "subtask", "after (s)", "why"], failed_rows) if failed_rows else "None."
    errors = "\n".join(f"- {r['part']} {r['map']}: {r['error']}" for r in results if "error" in r) or "None."
    sections = [("Setup", __doc__.split("\n\n", 2)[2]),
                ("Ours beside the paper", f"Paper: {PAPER}.\n\nOurs:\n\n{overall}\n\nPer lap:\n\n{laps}"),
                ("Subtasks that failed (skipped, the run went on) or were not reached", failed),
                ("Figures", "\n\n".join(f"![{p}]({p})" for p in pngs)),
                ("Crashed trials", errors)]
    write_markdown(out_dir, NAME, "E4 — long-term: aisle laps with pick-ups while boxes are rearranged", sections,
                   quick)


def build_trials(quick: bool) -> list[Trial]:
    laps = 1 if quick else LAPS
    maps = ("object", "voxel") if quick else ("object", "voxel", "ground_truth")
    trials = [Trial(trial, {"part": "laps", "map": m, "laps": laps}) for m in maps]
    if not quick:
        trials += [Trial(trial, {"part": "authored", "map": m, "laps": LAPS}) for m in ("object", "ground_truth")]
    return trials


def main(argv: list[str] | None = None) -> dict[str, float]:
    quiet_logs()
    args = experiment_args(NAME, __doc__.splitlines()[0], argv)
    results = trial_results(args, NAME, build_trials(args.quick), "E4 runs")
    figures = summarise(results)
    settings = {"aisle_m": AISLE_M, "laps": 1 if args.quick else LAPS, "spots": SPOTS, "loose_boxes": LOOSE,
                "change_at_subtask": change_points(1 if args.quick else LAPS),
                "layouts": layouts(SEED, len(change_points(1 if args.quick else LAPS)) + 1), "seed": SEED,
                "paper": PAPER}
    return finish_experiment(args, NAME, results, figures, settings, lambda out: figures_png(results, out),
                             lambda pngs: report(results, pngs, args.out, args.quick))


if __name__ == "__main__":
    main()
