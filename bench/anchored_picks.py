"""Anchored picks against the same picks in world coordinates, on boxes moved between laps.

    python -m bench.anchored_picks [--quick] [--seeds N] [--laps N] [--localization off|on|both]

`tasks/examples/anchored_picks.yaml` on its scene: per lap, pick above box_a and above box_c (each an EE
subtask whose stance the base drives to) and drive back to the start. At the start of every lap after the
first, each pick box moves 0.3–0.5 m in a seeded direction; a move after which the lap's authored targets break the
studio's own target checks on the true scene is drawn again (seed 0 once put box_a's approach stance 0.52 m from
box_b, where the base keeps 0.80 m: no controller reaches it, and the studio would refuse it; `moves_redrawn` in the
JSON counts them). The robot perceives through the whole sensor
model (depth noise, dropouts, flying pixels, camera latency, wheel odometry that drifts) into the object map
(POCD), with localization off and (`_localized` figures) on.

The same sequence runs twice on the same seeds: as authored (anchored on the named boxes) and with every
pick written in world coordinates where lap 1 had the boxes (what an operator writes today). Each completed
pick is measured against the simulator's TRUE box: the distance between the hand's true position when the
pick completes and the anchored pose on the true box then. A pick that times out counts as not completed.

Figures: `anchored_pick_error_m_median`, `anchored_pick_error_m_p95`, `anchored_picks_completed`,
`anchored_picks_on_box` (completed within `ON_BOX_M` of the true box), `anchored_subtasks_completed` (and the
`world_` ones beside them), JSON in `bench/results/anchored_picks.json`.
Target with localization off: anchored ≥ world-frame. A failed subtask stops the sequence (as in a run), so
later picks count as not completed.

Localization on: each variant runs a second time with the pose estimate corrected by registration
(`LocalizationParams.enabled`, as `bench.localization` switches it on); its figures go beside these with the
suffix `_localized` (target: every subtask of the anchored laps completed, 15 of 15 over 3 laps, on every seed).
Per pick the JSON also lists the variant, seed, lap, subtask, outcome and, for a completed pick, the error.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from app.footprint_overlap import overlap_depth
from app.runtime import Runtime, RuntimeConfig
from app.target_check import envelope_of, scene_obstacles
from core.params import LocalizationParams
from core.scene import load_scene
from tasks.anchors import MapObjects, ObjectView, anchor_position, resolve_subtask
from tasks.schema import Anchor, EESubtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR, load_sequence
from tasks.sequencer import Outcome
from tasks.validation import Obstacle, Severity, check_sequence

EXAMPLE = EXAMPLES_DIR / "anchored_picks.yaml"
RESULTS = Path(__file__).parent / "results"
MOVE_M = (0.3, 0.5)
MOVE_DRAWS = 200
"""Draws of one lap's moves before the bench gives up (a scene with no admissible move)."""
BOX_GAP_M = 0.05
"""A moved box keeps this much from every other box (no box is moved into another)."""
ON_BOX_M = 0.05
"""A completed pick within this of the anchored pose on the true box counts as on the box (`_picks_on_box`): the
pick's tolerance is 3 cm on what the robot believes; a world-frame pick completed at a moved box's old place
is completed, not on the box."""


def world_frame(sequence: TaskSequence, runtime: Runtime) -> TaskSequence:
    """The sequence with every anchored pose written in the world where the scene has its box now (lap 1)."""
    world = runtime.require_world()
    truth = MapObjects(0.0, tuple(_view(b.id, b) for b in world.boxes()))
    subtasks = []
    for sub in sequence.subtasks:
        placed, why = resolve_subtask(sub, truth)
        if placed is None:
            raise ValueError(f"{sub.name}: {why}")
        subtasks.append(placed)
    return sequence.model_copy(update={"subtasks": subtasks, "objects": {}})


def _view(name: str, box) -> ObjectView:
    return ObjectView("truth", name, np.asarray(box.position, float), float(box.yaw), np.asarray(box.size, float))


@dataclass
class _Trial:
    """Moves the pick boxes at each lap start after the first; measures each pick when it completes."""

    sequence: TaskSequence
    """The authored (anchored) laps: moves are drawn until its next lap passes the target checks."""
    anchors: dict[int, Anchor]
    lap_starts: tuple[int, ...]
    rng: np.random.Generator
    moves_redrawn: int = 0
    moved_at: set[int] = field(default_factory=set)
    errors: list[float] = field(default_factory=list)
    completed: int = 0
    last_index: int = 0
    picks: list[dict] = field(default_factory=list)
    """One row per pick attempted: subtask, outcome, error against the true box (m), the message."""
    subtasks_done: int = 0
    wall_s: float = 0.0

    def __call__(self, rt: Runtime) -> None:
        index = rt.sequencer.index
        if index != self.last_index:
            self._measure(rt, self.last_index)
            self.last_index = index
        if index in self.lap_starts and index not in self.moved_at:
            self.moved_at.add(index)
            for name, position in self._moves(rt, index).items():
                rt.move_box(name, position)

    def _moves(self, rt: Runtime, index: int) -> dict[str, tuple[float, float, float]]:
        """Seeded moves of the pick boxes for the lap starting at `index`, drawn again while the lap's targets
        break a target check on the true scene (the same draws for every variant: the robot plays no part)."""
        boxes = {o.id: o for o in scene_obstacles(rt)}
        names = sorted({a.object for a in self.anchors.values()})
        end = min([s for s in self.lap_starts if s > index] + [len(self.sequence.subtasks)])
        for _ in range(MOVE_DRAWS):
            moved = dict(boxes)
            for name in names:
                angle, dist = self.rng.uniform(0, 2 * math.pi), self.rng.uniform(*MOVE_M)
                x, y, z = boxes[name].position
                moved[name] = replace(boxes[name], position=(x + dist * math.cos(angle), y + dist * math.sin(angle), z))
            if _admissible(self.sequence, moved, names, range(index, end), rt):
                return {name: moved[name].position for name in names}
            self.moves_redrawn += 1
        raise RuntimeError(f"no admissible move of {names} in {MOVE_DRAWS} draws at subtask {index}")

    def _measure(self, rt: Runtime, index: int) -> None:
        anchor = self.anchors.get(index)
        if anchor is None:
            return
        progress = rt.sequencer.progress[index]
        box = rt.require_world().box(anchor.object)
        want = anchor_position(anchor, _view(anchor.object, box))
        backend = rt.backend
        q = backend.true_state().q if hasattr(backend, "true_state") else rt.state.q  # type: ignore[attr-defined]
        error = float(np.linalg.norm(rt.robot.ee_pose(q)[:3, 3] - want))
        done = progress.outcome == Outcome.DONE
        self.picks.append({"subtask": progress.name, "outcome": progress.outcome.name.lower(),
                           "error_m": round(error, 4), "message": progress.message,
                           "box": [round(float(v), 3) for v in box.position]})
        if done:
            self.errors.append(error)
            self.completed += 1


def _admissible(sequence: TaskSequence, boxes: dict[str, Obstacle], moved: list[str], lap: range, rt: Runtime) -> bool:
    """The moved boxes stand apart from the others and the lap's targets, placed on them, break no target check
    (without the path check: that depends on where this variant's robot stands)."""
    for name in moved:
        a = boxes[name]
        if any(o.id != name and overlap_depth(np.asarray(a.position), a.yaw, np.asarray(a.size), np.asarray(o.position),
                                              o.yaw, np.asarray(o.size)) > -BOX_GAP_M for o in boxes.values()):
            return False
    findings = check_sequence(sequence, tuple(boxes.values()), envelope_of(rt), indices=lap,
                              anchors={name: boxes[name] for name in moved})
    return not any(f.severity == Severity.ERROR for f in findings)


def run(sequence: TaskSequence, authored: TaskSequence, anchors: dict[int, Anchor], lap_starts: tuple[int, ...],
        seed: int, max_s: float, localization: bool = False) -> _Trial:
    """One run of `sequence` on seed `seed` (boxes moved as `authored` admits), with the pose estimate corrected
    by registration if `localization`."""
    scene = load_scene((EXAMPLE.parent / (sequence.scene or "")).resolve())
    config = RuntimeConfig(map_kind="object", seed=seed, localization=LocalizationParams(enabled=localization))
    rt = Runtime(config, scene=scene, sequence=sequence)
    trial = _Trial(authored, anchors, lap_starts, np.random.default_rng(seed))
    t0 = time.perf_counter()
    rt.run_lockstep(max_s, on_control=trial)
    trial.wall_s = time.perf_counter() - t0
    if trial.last_index in anchors and not any(p["subtask"] == rt.sequencer.progress[trial.last_index].name
                                                 for p in trial.picks):
        trial._measure(rt, trial.last_index)
    trial.subtasks_done = sum(p.outcome == Outcome.DONE for p in rt.sequencer.progress)
    rt.shutdown()
    return trial


def laps_of(sequence: TaskSequence, laps: int) -> tuple[TaskSequence, tuple[int, ...]]:
    """The one-lap example repeated `laps` times, and the subtask index at which each later lap starts."""
    n = len(sequence.subtasks)
    subtasks = [s.model_copy(update={"name": f"lap {k + 1}: {s.name}"}) for k in range(laps) for s in sequence.subtasks]
    return sequence.model_copy(update={"subtasks": subtasks}), tuple(k * n for k in range(1, laps))


LOCALIZATION = {"off": (False,), "on": (True,), "both": (False, True)}


def figures_of(kind: str, trials: list[_Trial]) -> dict[str, float]:
    """The figures of one variant (`kind`: anchored, world, anchored_localized, world_localized)."""
    errors = np.array([e for t in trials for e in t.errors])
    base, _, suffix = kind.partition("_")
    suffix = f"_{suffix}" if suffix else ""
    return {f"{base}_pick_error_m_median{suffix}": float(np.median(errors)) if len(errors) else math.nan,
            f"{base}_pick_error_m_p95{suffix}": float(np.percentile(errors, 95)) if len(errors) else math.nan,
            f"{base}_picks_completed{suffix}": float(sum(t.completed for t in trials)),
            f"{base}_picks_on_box{suffix}": float(sum(e <= ON_BOX_M for e in errors)),
            f"{base}_subtasks_completed{suffix}": float(sum(t.subtasks_done for t in trials))}


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one seed, two laps")
    parser.add_argument("--seeds", type=int, default=None)
    parser.add_argument("--laps", type=int, default=None)
    parser.add_argument("--localization", choices=tuple(LOCALIZATION), default="both",
                        help="run with localization off, on, or both (default)")
    parser.add_argument("--workers", type=int, default=2, help="runs side by side (processes)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    seeds = args.seeds or (1 if args.quick else 5)
    laps = args.laps or (2 if args.quick else 3)
    authored, lap_starts = laps_of(load_sequence(EXAMPLE), laps)
    anchors = {i: a for i, s in enumerate(authored.subtasks)
               if isinstance(s, EESubtask) and (a := s.goal().anchor) is not None}
    max_s = sum(s.timeout_s for s in authored.subtasks)
    t0 = time.time()
    scene_rt = Runtime(RuntimeConfig(map_kind="ground_truth"),
                       scene=load_scene((EXAMPLE.parent / (authored.scene or "")).resolve()), sequence=authored)
    variants = {"anchored": authored, "world": world_frame(authored, scene_rt)}
    scene_rt.shutdown()
    out: dict[str, list[_Trial]] = {}
    rows: list[dict] = []
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=get_context("spawn")) as pool:
        jobs = {pool.submit(run, seq, authored, anchors, lap_starts, seed, max_s, loc):
                (kind + ("_localized" if loc else ""), seed)
                for loc in LOCALIZATION[args.localization] for seed in range(seeds) for kind, seq in variants.items()}
        for job, (kind, seed) in jobs.items():
            trial = job.result()
            out.setdefault(kind, []).append(trial)
            rows += [{"variant": kind, "seed": seed, **p} for p in trial.picks]
            rows.append({"variant": kind, "seed": seed, "subtasks_completed": trial.subtasks_done,
                         "moves_redrawn": trial.moves_redrawn, "wall_s": round(trial.wall_s, 1)})
    figures: dict[str, float] = {}
    for kind, trials in out.items():
        figures.update(figures_of(kind, trials))
    figures["picks_attempted"] = float(len(anchors) * seeds)
    figures["subtasks_attempted"] = float(len(authored.subtasks) * seeds)
    units = {k: ("m" if "_m_" in k else "picks" if "picks" in k else "subtasks") for k in figures}
    result = {"bench": "anchored_picks", "when": datetime.now(UTC).isoformat(timespec="seconds"), "quick": args.quick,
              "machine": {"cpu": platform.processor() or platform.machine(), "cores": _cores(),
                          "python": platform.python_version()},
              "figures": figures, "units": units,
              "targets": {"anchored_picks_completed": ">= world_picks_completed (localization off)",
                          "anchored_subtasks_completed_localized": "== subtasks_attempted (localization on)"},
              "config": {"seeds": seeds, "laps": laps, "move_m": list(MOVE_M), "map": "object",
                         "sensor": "SimParams.sensor (drifting odometry)", "localization": args.localization,
                         "stops_at_first_failed_subtask": True,
                         "wall_s": round(time.time() - t0, 1)},
              "picks": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "anchored_picks.json").write_text(json.dumps(result, indent=2))
    width = max(map(len, figures))
    for k, v in figures.items():
        print(f"{k:<{width}}  {v:.3f} {units[k]}")
    return figures


def _cores() -> int:
    import os

    return os.cpu_count() or 0


if __name__ == "__main__":
    main()
