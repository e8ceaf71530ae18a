"""The closed loop as a user runs it: lockstep real-time factor with mapping and HTMPC on, latency
from a box move (as the UI makes it) to its constraint in the controller in live mode, the UI
update rate, and live driving through the hardware bridge with two CPU burners beside it (stale-state
pauses, late control periods, the real command rate and its gaps: bench/bridge_driving.py).

    python -m bench.closed_loop [--quick] [--bridge-only | --reaction-only]

Reaction (`reaction_ms_*`, `processing_ms_*`, bench/reaction.py): live, a box put in front of the robot driving
at 1 m/s, wall ms from the placement to the first command that slows it, split into its stages.
"""

from __future__ import annotations

import argparse
import socket
import time
from dataclasses import dataclass, field

import numpy as np

import core.sim  # noqa: F401  (GL backend first)
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from bench.bridge_driving import drive
from bench.reaction import ReactionRun, measure_reactions
from bench.reaction_chain import PARTS, Reaction
from bench.report import percentile, write_result
from core.params import MappingParams
from core.scene import PAPER_BOX_M, Box, Scene, random_scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR, load_sequence

BURNERS = 2
BRIDGE_FULL_S = 300.0
BRIDGE_QUICK_S = 30.0


def lockstep_rtf(seconds: float) -> tuple[float, dict[str, float]]:
    """Sim seconds per wall second for the paper's navigation run with the object map, cameras and HTMPC."""
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=random_scene(0),
                 sequence=load_sequence(EXAMPLES_DIR / "navigation_through_boxes.yaml"))
    t0 = time.perf_counter()
    log = rt.run_lockstep(seconds)
    wall = time.perf_counter() - t0
    timings = {k: percentile([t.get(k, np.nan) for t in log.timings_ms], 50) for k in ("mapping", "edf", "solve")}
    return (rt.time / wall), {**timings, "finished": float(rt.run_state == RunState.FINISHED)}


@dataclass
class BoxMoveLatencies:
    """Wall ms from each box move to the first control step whose EDF holds it: its face towards the robot
    (what the collision rows see), and the solid box at its centre (box completion, `completion.py`)."""

    to_constraint_ms: list[float] = field(default_factory=list)
    to_solid_ms: list[float] = field(default_factory=list)


def box_move_latency(trials: int) -> BoxMoveLatencies:
    """Live mode: a box is put 2 m ahead of the robot (as the UI's move does), beside its path, alternately
    left and right; time until a control step's EDF shows the face towards the robot within one EDF voxel
    (the constraint sees the box), and until it reads inside the box at its centre (the box completed)."""
    far = (0.0, 8.0, 0.3)
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("probe", far),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=0.0, y=0.0, yaw_deg=0.0),
                                                             timeout_s=1e4, dwell_s=1e4)]))
    near_enough_m = MappingParams().edf_voxel_m
    out = BoxMoveLatencies()
    rt.start_live()
    rt.start()
    try:
        time.sleep(1.5)
        for i in range(trials):
            centre = np.array([2.0, -0.6 + 1.2 * (i % 2), 0.3])
            face = centre - [PAPER_BOX_M / 2, 0.0, 0.0]
            wall0 = time.time()
            rt.move_box("probe", tuple(centre))
            seen_face = None
            while time.time() - wall0 < 3.0:
                edf, stepped = rt.last_edf, rt.last_control_wall
                if stepped > wall0 and edf is not None:
                    if seen_face is None and edf.distance(face) <= near_enough_m:
                        seen_face = (stepped - wall0) * 1e3
                        out.to_constraint_ms.append(seen_face)
                    if edf.distance(centre) < 0.0:
                        out.to_solid_ms.append((stepped - wall0) * 1e3)
                        break
                time.sleep(0.002)
            rt.move_box("probe", far)
            time.sleep(1.5)  # the map forgets it again
    finally:
        rt.shutdown()
    return out


REACTION_EVENTS = {True: 10, False: 100}
"""Reactions measured in a quick and a full run."""


def reaction_figures(run: ReactionRun[Reaction]) -> dict[str, float]:
    """Reaction to a box put in the robot's way, live (bench/reaction.py): the whole, its parts (p50 and p95),
    the part after the frame's stamp, and the same reaction in simulated time."""
    total = [r.total_ms for r in run.reactions]
    figures = {"reaction_ms_p50": percentile(total, 50), "reaction_ms_p95": percentile(total, 95),
               "reaction_ms_max": max(total, default=float("nan")),
               "processing_ms_p50": percentile([r.processing_ms for r in run.reactions], 50),
               "processing_ms_p95": percentile([r.processing_ms for r in run.reactions], 95),
               "reaction_sim_ms_p50": percentile([r.sim_ms for r in run.reactions], 50),
               "reaction_sim_ms_p95": percentile([r.sim_ms for r in run.reactions], 95),
               "reaction_events": float(len(run.reactions)), "reaction_placements": float(run.placements),
               "reaction_constrained": float(run.constrained), "reaction_rejected": float(len(run.rejected)),
               "reaction_mapping_queue_ms_p50": percentile([r.mapping_queue_ms for r in run.reactions], 50),
               "reaction_mapping_queue_ms_p95": percentile([r.mapping_queue_ms for r in run.reactions], 95)}
    for part in PARTS:
        values = [r.parts_ms[part] for r in run.reactions]
        figures |= {f"reaction_{part}_ms_p50": percentile(values, 50),
                    f"reaction_{part}_ms_p95": percentile(values, 95)}
    return figures


def ui_update_rate(seconds: float) -> float:
    """Snapshots drawn by the studio per second while a sequence runs live."""
    from app.ui.studio import Studio

    rt = Runtime(RuntimeConfig(map_kind="object"), scene=random_scene(0),
                 sequence=load_sequence(EXAMPLES_DIR / "navigation_through_boxes.yaml"))
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    studio = Studio(rt, port=port)
    rt.start_live()
    rt.start()
    try:
        time.sleep(1.0)
        n0, t0 = studio.draws, time.perf_counter()
        time.sleep(seconds)
        return (studio.draws - n0) / (time.perf_counter() - t0)
    finally:
        rt.shutdown()
        studio.close()


REACTION_UNITS = {k: "ms" for k in ("reaction_ms_p50", "reaction_ms_p95", "reaction_ms_max", "processing_ms_p50",
                                     "processing_ms_p95", "reaction_sim_ms_p50", "reaction_sim_ms_p95")}
REACTION_UNITS |= {f"reaction_{part}_ms_p{q}": "ms" for part in PARTS for q in (50, 95)}
REACTION_TARGETS = {"reaction_ms_p95": "<= 100", "processing_ms_p95": "<= 40"}
"""Issue 33's targets, live on a quiet machine."""
UNITS = {"lockstep_rtf": "x", "box_move_to_constraint_ms": "ms", "box_move_to_constraint_p95_ms": "ms",
         "box_move_to_solid_ms": "ms", "box_move_to_solid_p95_ms": "ms",
         "ui_update_hz": "Hz", "lockstep_mapping_ms": "ms", "lockstep_edf_ms": "ms", "lockstep_solve_ms": "ms",
         "bridge_driving_s": "s", "control_periods_late_pct": "%", "command_rate_hz": "Hz",
         "command_gap_p50_ms": "ms", "command_gap_p99_ms": "ms", "command_gap_max_ms": "ms",
         "runtime_cpu_pct": "% of a core", "command_gap_max_after_restart_s": "s"}
TARGETS = {"lockstep_rtf": ">= 2", "box_move_to_constraint_ms": "<= 300", "box_move_to_constraint_p95_ms": "<= 300",
           "stale_pauses": "== 0", "control_periods_late_pct": "<= 1", "command_rate_hz": ">= 99",
           "bridge_faults": "== 0"}


def reaction_part(quick: bool) -> tuple[dict[str, float], dict]:
    """The reaction figures and, for the JSON, every reaction and why placements gave none."""
    run = measure_reactions(REACTION_EVENTS[quick], max_wall_s=120.0 if quick else 1200.0)
    reactions = [{"total_ms": r.total_ms, "sim_ms": r.sim_ms, "camera": r.camera, "h_m": r.h_m,
                  "v_before_mps": r.v_before_mps, "v_after_mps": r.v_after_mps, "later_plans": r.later_plans,
                  "unseen_frames": r.unseen_frames, **r.parts_ms} for r in run.reactions]
    return reaction_figures(run), {"reaction_rejected": run.rejected[:30], "reactions": reactions}


def simulation_part(quick: bool) -> dict[str, float]:
    """Lockstep rate, box move to constraint, UI rate."""
    rtf, stage_ms = lockstep_rtf(20.0 if quick else 40.0)
    moves = box_move_latency(6 if quick else 30)
    ui_hz = ui_update_rate(5.0 if quick else 15.0)
    return {"lockstep_rtf": rtf, "box_move_to_constraint_ms": percentile(moves.to_constraint_ms, 50),
            "box_move_to_constraint_p95_ms": percentile(moves.to_constraint_ms, 95),
            "box_moves_seen": float(len(moves.to_constraint_ms)),
            "box_move_to_solid_ms": percentile(moves.to_solid_ms, 50),
            "box_move_to_solid_p95_ms": percentile(moves.to_solid_ms, 95),
            "box_moves_completed": float(len(moves.to_solid_ms)), "ui_update_hz": ui_hz,
            "lockstep_mapping_ms": stage_ms["mapping"], "lockstep_edf_ms": stage_ms["edf"],
            "lockstep_solve_ms": stage_ms["solve"], "navigation_finished": stage_ms["finished"]}


def bridge_part(args: argparse.Namespace) -> tuple[dict[str, float], dict]:
    """Live driving through the bridge with two CPU burners beside it (bench/bridge_driving.py)."""
    driving = drive(BRIDGE_QUICK_S if args.quick else BRIDGE_FULL_S, burners=BURNERS,
                    burner_niceness=args.burner_nice, raise_priority=not args.normal_priority)
    figures = {"bridge_driving_s": driving.duration_s, "burners": float(BURNERS),
               "burner_niceness": float(args.burner_nice), "raised_priority": float(not args.normal_priority),
               **driving.figures()}
    return figures, {"bridge_faults": driving.faults, "bridge_subtask_failures": driving.subtask_failures[:30],
                     "load_before": driving.load_before, "load_after": driving.load_after}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--quick", action="store_true", help="short run with the same figures")
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--bridge-only", action="store_true", help="only the bridge driving figures")
    only.add_argument("--reaction-only", action="store_true", help="only the reaction figures (bench/reaction.py)")
    parser.add_argument("--burner-nice", type=int, default=0,
                        help="niceness of the CPU burners relative to this process (0: same priority; 10: background)")
    parser.add_argument("--normal-priority", action="store_true",
                        help="runtime and driver at normal priority (app/thread_priority.py off), for comparison")
    args = parser.parse_args(argv)
    figures: dict[str, float] = {}
    extra: dict = {}
    if not args.bridge_only:
        reaction, extra = reaction_part(args.quick)
        figures |= reaction
    if not (args.bridge_only or args.reaction_only):
        figures |= simulation_part(args.quick)
    if not args.reaction_only:
        bridge, bridge_extra = bridge_part(args)
        figures, extra = figures | bridge, extra | bridge_extra
    write_result("closed_loop", figures, UNITS | REACTION_UNITS, TARGETS | REACTION_TARGETS, quick=args.quick,
                 extra=extra)


if __name__ == "__main__":
    main()
