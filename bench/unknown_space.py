"""Unknown space as an obstacle (docs/method.md, "Unknown space is not free"): the base drives at 1 m/s toward a
wall whose surface returns no depth (never mapped), its goal behind it, with unknown space as an obstacle
(`MappingParams.unknown_space = 'obstacle'`) and as the paper has it ('free'); and what the evidence costs a frame.

    python -m bench.unknown_space [--quick]

Figures (lockstep, object map, the sensor model on, reference speed 1 m/s):
- `stop_peak_speed_mps`: the base's top speed toward the wall before it slowed (that it did reach 1 m/s);
- `stop_clearance_m`: robot–wall distance when the base first came to rest toward the wall (its speed toward
  the wall under 0.05 m/s), `stop_min_distance_m` the smallest over the run, `stop_collision_events` contacts;
- `free_collision_events`, `free_min_distance_m`: the same run with unknown space free (the paper);
- `unknown_integrate_cpu_ms`, `unknown_edf_cpu_ms`: median CPU time (thread time: a loaded machine inflates wall
  time) of one frame's evidence (its rays checked against the robot's body too) and of joining the columns to
  the field.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

import core.sim  # noqa: F401  (GL backend first)
from app.runtime import Runtime, RuntimeConfig
from bench.report import bench_args, percentile, write_result
from core.mapping.self_filter import SelfFilter
from core.mapping.unknown_floor import UnknownFloor, unknown_columns
from core.params import MappingParams, SequencerParams
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence

WALL = Box("dark_wall", (5.0, 0.0, 0.5), (0.4, 12.0, 1.0), dark=True)
"""Too wide to go round in the run: the base must stop before it (its face at x = 4.8 m)."""
GOAL = (7.0, 0.0)
REST_MPS = 0.05


def drive(unknown_space: str, seconds: float) -> tuple[dict[str, float], Runtime]:
    """One run toward the wall; figures of the approach."""
    config = RuntimeConfig(map_kind="object", mapping=replace(MappingParams(), unknown_space=unknown_space),
                           sequencer=replace(SequencerParams(), nominal_speed_mps=1.0))
    sequence = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=GOAL[0], y=GOAL[1]), timeout_s=seconds + 5)])
    rt = Runtime(config, scene=Scene((WALL,), robot_start=(0.0, 0.0, 0.0)), sequence=sequence)
    log = rt.run_lockstep(seconds)
    assert rt.world is not None, "the embedded simulation"
    toward = np.array([v[0] for v in log.v])  # the wall is straight ahead, along +x
    distance = np.array(log.min_distance_m, float)
    peak = int(np.argmax(toward))
    rest = np.nonzero(toward[peak:] < REST_MPS)[0]
    clearance = float(distance[peak + rest[0]]) if len(rest) else float("nan")
    return {"peak_speed_mps": float(toward[peak]), "clearance_m": clearance,
            "min_distance_m": float(np.nanmin(distance)), "collision_events": float(len(rt.world.collisions)),
            "slowed_steps": float(rt.closed_loop.unknown_slowed_steps)}, rt


def evidence_cost(rt: Runtime, repeats: int) -> dict[str, float]:
    """Median ms of integrating one frame's unknown-floor evidence, and of joining the columns to a field."""
    params = MappingParams()
    frames = [f for f in rt.latest_frames.values() if f.camera in params.unknown_cameras]
    floor = UnknownFloor(params)
    body = SelfFilter(rt.robot, params.self_filter_margin_m).body(rt.state.q)
    integrate, join = [], []
    edf = rt.closed_loop.last_edf
    for _ in range(repeats):
        for frame in frames:
            t0 = time.thread_time()
            floor.integrate(frame, body)
            integrate.append((time.thread_time() - t0) * 1e3)
        if edf is not None:
            t0 = time.thread_time()
            unknown_columns(edf, floor.space())
            join.append((time.thread_time() - t0) * 1e3)
    return {"unknown_integrate_cpu_ms": percentile(integrate, 50), "unknown_edf_cpu_ms": percentile(join, 50)}


def main(argv: list[str] | None = None) -> None:
    args = bench_args("unknown space as an obstacle: stopping before a wall that returns no depth", argv)
    seconds = 9.0 if args.quick else 15.0
    guarded, rt = drive("obstacle", seconds)
    free, _ = drive("free", seconds)
    figures = {f"stop_{k}": v for k, v in guarded.items()}
    figures |= {"free_collision_events": free["collision_events"], "free_min_distance_m": free["min_distance_m"],
                "free_peak_speed_mps": free["peak_speed_mps"]}
    figures |= evidence_cost(rt, 5 if args.quick else 20)
    units = {k: ("m/s" if k.endswith("mps") else "m" if k.endswith("_m") else "ms" if k.endswith("ms") else "")
             for k in figures}
    targets = {"stop_collision_events": "== 0", "stop_min_distance_m": "> 0", "stop_peak_speed_mps": ">= 0.95"}
    write_result("unknown_space", figures, units, targets, quick=args.quick)


if __name__ == "__main__":
    main()
