"""Anchored picks against the same picks in world coordinates, on boxes moved between laps.

    python -m bench.anchored_picks [--quick] [--seeds N] [--laps N]

`tasks/examples/anchored_picks.yaml` on its scene: per lap, pick above box_3 and above box_5 (each an EE
subtask whose stance the base drives to) and drive back to the start. At the start of every lap after the
first, each pick box moves 0.3–0.5 m in a seeded direction. The robot perceives through the whole sensor
model (depth noise, dropouts, flying pixels, camera latency, wheel odometry that drifts) into the object map
(POCD); localization is off (issue 25 adds the figures with it on).

The same sequence runs twice on the same seeds: as authored (anchored on the named boxes) and with every
pick written in world coordinates where lap 1 had the boxes (what an operator writes today). Each completed
pick is measured against the simulator's TRUE box: the distance between the hand's true position when the
pick completes and the anchored pose on the true box then. A pick that times out counts as not completed.

Figures: `anchored_pick_error_m_median`, `anchored_pick_error_m_p95`, `anchored_picks_completed` (and the
`world_` ones beside them), JSON in `bench/results/anchored_picks.json`. Target with localization off:
anchored ≥ world-frame. A failed subtask stops the sequence (as in a run), so later picks count as not
completed.

Localization on (issue 25, not in yet): each variant runs a second time with the pose estimate corrected
by registration; its figures go beside these with the suffix `_localized` (target: every anchored pick
completed, 15/15 over 3 laps), from `run(..., localization=True)` once `RuntimeConfig` can switch it on.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from datetime import UTC, datetime
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from app.runtime import Runtime, RuntimeConfig
from core.scene import load_scene
from tasks.anchors import MapObjects, ObjectView, anchor_position, resolve_subtask
from tasks.schema import Anchor, EESubtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR, load_sequence
from tasks.sequencer import Outcome

EXAMPLE = EXAMPLES_DIR / "anchored_picks.yaml"
RESULTS = Path(__file__).parent / "results"
MOVE_M = (0.3, 0.5)


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

    anchors: dict[int, Anchor]
    lap_starts: tuple[int, ...]
    rng: np.random.Generator
    moved_at: set[int] = field(default_factory=set)
    errors: list[float] = field(default_factory=list)
    completed: int = 0
    last_index: int = 0

    def __call__(self, rt: Runtime) -> None:
        index = rt.sequencer.index
        if index != self.last_index:
            self._measure(rt, self.last_index)
            self.last_index = index
        if index in self.lap_starts and index not in self.moved_at:
            self.moved_at.add(index)
            for name in sorted({a.object for a in self.anchors.values()}):
                box = rt.require_world().box(name)
                angle = self.rng.uniform(0, 2 * math.pi)
                dist = self.rng.uniform(*MOVE_M)
                rt.move_box(name, (box.position[0] + dist * math.cos(angle), box.position[1] + dist * math.sin(angle),
                                   box.position[2]))

    def _measure(self, rt: Runtime, index: int) -> None:
        anchor = self.anchors.get(index)
        if anchor is None or rt.sequencer.progress[index].outcome != Outcome.DONE:
            return
        backend = rt.backend
        q = backend.true_state().q if hasattr(backend, "true_state") else rt.state.q  # type: ignore[attr-defined]
        box = rt.require_world().box(anchor.object)
        want = anchor_position(anchor, _view(anchor.object, box))
        self.errors.append(float(np.linalg.norm(rt.robot.ee_pose(q)[:3, 3] - want)))
        self.completed += 1


def run(sequence: TaskSequence, anchors: dict[int, Anchor], lap_starts: tuple[int, ...], seed: int,
        max_s: float) -> _Trial:
    scene = load_scene((EXAMPLE.parent / (sequence.scene or "")).resolve())
    rt = Runtime(RuntimeConfig(map_kind="object", seed=seed), scene=scene, sequence=sequence)
    trial = _Trial(anchors, lap_starts, np.random.default_rng(seed))
    rt.run_lockstep(max_s, on_control=trial)
    trial._measure(rt, trial.last_index)
    return trial


def laps_of(sequence: TaskSequence, laps: int) -> tuple[TaskSequence, tuple[int, ...]]:
    """The one-lap example repeated `laps` times, and the subtask index at which each later lap starts."""
    n = len(sequence.subtasks)
    subtasks = [s.model_copy(update={"name": f"lap {k + 1}: {s.name}"}) for k in range(laps) for s in sequence.subtasks]
    return sequence.model_copy(update={"subtasks": subtasks}), tuple(k * n for k in range(1, laps))


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="one seed, two laps")
    parser.add_argument("--seeds", type=int, default=None)
    parser.add_argument("--laps", type=int, default=None)
    parser.add_argument("--workers", type=int, default=2, help="runs side by side (processes)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    seeds = args.seeds or (1 if args.quick else 5)
    laps = args.laps or (2 if args.quick else 3)
    authored, lap_starts = laps_of(load_sequence(EXAMPLE), laps)
    anchors = {i: s.goal().anchor for i, s in enumerate(authored.subtasks)
               if isinstance(s, EESubtask) and s.goal().anchor is not None}
    max_s = sum(s.timeout_s for s in authored.subtasks)
    t0 = time.time()
    scene_rt = Runtime(RuntimeConfig(map_kind="ground_truth"),
                       scene=load_scene((EXAMPLE.parent / (authored.scene or "")).resolve()), sequence=authored)
    variants = {"anchored": authored, "world": world_frame(authored, scene_rt)}
    scene_rt.shutdown()
    out: dict[str, list[_Trial]] = {k: [] for k in variants}
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=get_context("spawn")) as pool:
        jobs = {pool.submit(run, seq, anchors, lap_starts, seed, max_s): kind
                for seed in range(seeds) for kind, seq in variants.items()}
        for job, kind in jobs.items():
            out[kind].append(job.result())
    figures: dict[str, float] = {}
    for kind, trials in out.items():
        errors = np.array([e for t in trials for e in t.errors])
        figures[f"{kind}_pick_error_m_median"] = float(np.median(errors)) if len(errors) else math.nan
        figures[f"{kind}_pick_error_m_p95"] = float(np.percentile(errors, 95)) if len(errors) else math.nan
        figures[f"{kind}_picks_completed"] = float(sum(t.completed for t in trials))
    figures["picks_attempted"] = float(len(anchors) * seeds)
    units = {k: ("m" if k.endswith("_m_median") or k.endswith("_m_p95") else "picks") for k in figures}
    result = {"bench": "anchored_picks", "when": datetime.now(UTC).isoformat(timespec="seconds"), "quick": args.quick,
              "machine": {"cpu": platform.processor() or platform.machine(), "cores": _cores(),
                          "python": platform.python_version()},
              "figures": figures, "units": units,
              "targets": {"anchored_picks_completed": ">= world_picks_completed (localization off)"},
              "config": {"seeds": seeds, "laps": laps, "move_m": list(MOVE_M), "map": "object",
                         "sensor": "SimParams.sensor (drifting odometry)", "localization": "off",
                         "stops_at_first_failed_subtask": True,
                         "wall_s": round(time.time() - t0, 1)}}
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
