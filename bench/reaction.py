"""Reaction time, live: boxes put in front of the robot driving at 1 m/s on the embedded simulation, and the time
from the placement to the first command that slows it (`bench/reaction_chain.py` reads the chain of stages).

The robot shuttles along a 14 m line (the E3 experiment's, in the sequencer's grid) with the product's controller
and map (object map in its own process, sensor model, CBF with gamma and delta_safe of `HTMPCParams`); its
references advance at 1 m/s (the base limit). Once it cruises (>= `CRUISE_MPS` along its heading, at least
`ROOM_M` before the end of the line), a 0.6 m box appears straight ahead with its near face `GAP_M` beyond the
base's front: its barrier h = GAP_M - delta_safe (0.75 m) is below v / gamma (1 m) then, so the constraint must
act. Once the reaction is read (or after `WAIT_S`), the box goes back out of the way and the robot drives on; the
map forgets it from the frames that see the place empty.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Generic, TypeVar

import numpy as np

from app.runtime import Runtime, RuntimeConfig
from app.runtime.stage_stamps import StageStamps
from bench.experiments.measures import body_distance, body_reach_m
from bench.reaction_chain import Placement, Reaction, analyse
from core.scene import PAPER_BOX_M, Box, Scene
from core.sim.world import SimWorld
from core.types import RobotBackend, RobotState
from tasks import BasePose, BaseSubtask, Subtask, TaskSequence

log = logging.getLogger(__name__)

SPEED_MPS = 1.0
LINE_X_M = 7.0
CRUISE_MPS = 0.85
ROOM_M = 4.0
GAP_M = 1.0
PARK = (-20.0, 20.0, PAPER_BOX_M / 2)
WAIT_S = 1.5
"""Longest wait for a reaction after a placement (wall s)."""
FORGET_S = 0.8
"""After the box is parked again: time for the map to see its place empty before the next (wall s)."""
LEGS = 400


R = TypeVar("R")


@dataclass
class ReactionRun(Generic[R]):
    """The reactions measured (with their placements), the placements that gave none (with why), and the stamps
    they were read from (the latest `keep_s` of them)."""

    stamps: StageStamps
    events: list[tuple[Placement, R]] = field(default_factory=list)
    rejected: list[str] = field(default_factory=list)
    constrained: int = 0
    """Placements whose barrier h was below v / gamma when the box appeared."""
    placements: int = 0
    health: dict[str, float] = field(default_factory=dict)
    """How the live loops kept time meanwhile (`loop_health`)."""

    @property
    def reactions(self) -> list[R]:
        return [reaction for _, reaction in self.events]

    def trial(self, placement: Placement, gamma: float, react: Callable[[Placement], R | str],
              park: Callable[[], object]) -> None:
        """One placement: its reaction read (or why none), the box parked, time for the map to forget it."""
        self.placements += 1
        self.constrained += int(placement.h_m < placement.v_before_mps / gamma)
        result = react(placement)
        park()
        if isinstance(result, str):
            self.rejected.append(result)
            log.info("placement %d: %s", self.placements, result)
        else:
            self.events.append((placement, result))
        time.sleep(FORGET_S)


def shuttle() -> TaskSequence:
    """Back and forth along the line, facing the way it drives (so the base camera looks ahead)."""
    legs: list[Subtask] = [BaseSubtask(name=f"leg {i}", target=BasePose(x=LINE_X_M * (1 if i % 2 == 0 else -1), y=0.0,
                                                          yaw_deg=0.0 if i % 2 == 0 else 180.0), timeout_s=120.0)
            for i in range(LEGS)]
    return TaskSequence(name="shuttle", subtasks=legs)


def reaction_scene() -> Scene:
    """An empty floor with one parked box, the robot at the start of the line."""
    return Scene((Box("probe", PARK),), robot_start=(-LINE_X_M, 0.0, 0.0), name="reaction")


def reaction_runtime(config: RuntimeConfig | None = None, backend: RobotBackend | None = None) -> Runtime:
    """The shuttle, references at `SPEED_MPS`: on `reaction_scene` simulated here, or driving `backend` (a
    robot behind the bridge, whose driver simulates that scene)."""
    config = config or RuntimeConfig(map_kind="object")
    config = replace(config, sequencer=replace(config.sequencer, nominal_speed_mps=SPEED_MPS))
    if backend is not None:
        return Runtime(config, sequence=shuttle(), backend=backend)
    return Runtime(config, scene=reaction_scene(), sequence=shuttle())


def cruising(rt: Runtime) -> bool:
    """Driving along its heading at speed, with room ahead before the end of the line (the true state)."""
    return cruising_at(rt.require_world().state())


def cruising_at(state: RobotState) -> bool:
    """Whether `state` drives along its heading at `CRUISE_MPS` or more, `ROOM_M` or more before the line's end."""
    q, v = state.q, state.v
    heading = np.array([math.cos(q[2]), math.sin(q[2])])
    ahead_x = LINE_X_M - q[0] if heading[0] > 0 else q[0] + LINE_X_M
    return float(v[:2] @ heading) >= CRUISE_MPS and abs(heading[0]) > 0.98 and ahead_x >= ROOM_M


@dataclass(frozen=True)
class BoxAhead:
    """Where the box goes: its centre and yaw in the true world, points on it, the point of its face towards the
    robot and the unit direction from the base to it, in the world the robot believes in."""

    centre: tuple[float, float, float]
    yaw: float
    points: np.ndarray
    face: np.ndarray
    towards: np.ndarray


def box_ahead(world: SimWorld, q: np.ndarray, believed: np.ndarray) -> BoxAhead:
    """The box straight ahead of the base at true pose `q`, its near face `GAP_M` beyond the base's front, seen
    from the believed pose `believed` (odometry drifts: the map, the EDF, the frames and the commands are all in
    the believed world)."""
    heading = np.array([math.cos(q[2]), math.sin(q[2])])
    centre = q[:2] + heading * (body_reach_m(world, "base", q) + GAP_M + PAPER_BOX_M / 2)
    to_believed = believed_frame(q, believed)
    axes = np.array([[heading[0], heading[1], 0.0], [-heading[1], heading[0], 0.0], [0.0, 0.0, 1.0]])
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    centre3 = np.array([*centre, PARK[2]])
    points = to_believed(np.vstack([centre3, centre3 + PAPER_BOX_M / 2 * signs @ axes,
                                    centre3 - axes[0] * PAPER_BOX_M / 2]))
    towards = to_believed(np.array([[*heading, 0.0]]), rotate_only=True)[0, :2]
    return BoxAhead((float(centre[0]), float(centre[1]), PARK[2]), float(q[2]), points[:-1], points[-1], towards)


def velocity_before(stamps: StageStamps, wall: float, towards: np.ndarray) -> float:
    """The base velocity towards the box of the last command before `wall` (NaN: none)."""
    before = [c for c in list(stamps.commands) if c.wall <= wall]
    return float(np.dot(before[-1].base_v, towards)) if before else float("nan")


def place(rt: Runtime, stamps: StageStamps) -> Placement:
    """The box straight ahead (`box_ahead`), the placement as it happened, in the world the robot believes in."""
    world = rt.require_world()
    with world.lock:  # no physics step between the edit and reading its time
        q = world.state().q
        ahead = box_ahead(world, q, rt.state.q)  # the loop's estimate, at most one I/O period (10 ms) older
        rt.move_box("probe", ahead.centre, ahead.yaw)
        t, wall = world.time, stamps.now()
        h = body_distance(world, "base", (world.box("probe"),)) - rt.controller.params.delta_safe_m
    return Placement(wall, t, ahead.points, ahead.face, ahead.towards,
                     velocity_before(stamps, wall, ahead.towards), h)


def believed_frame(true_q: np.ndarray, believed_q: np.ndarray):
    """Points of the true world (P×3) in the world the robot believes in, from its true and believed base pose."""
    dyaw = float(believed_q[2] - true_q[2])
    R = np.array([[math.cos(dyaw), -math.sin(dyaw), 0.0], [math.sin(dyaw), math.cos(dyaw), 0.0], [0.0, 0.0, 1.0]])
    shift = np.array([believed_q[0], believed_q[1], 0.0])
    origin = np.array([true_q[0], true_q[1], 0.0])

    def transform(points: np.ndarray, rotate_only: bool = False) -> np.ndarray:
        return points @ R.T if rotate_only else (points - origin) @ R.T + shift
    return transform


def await_reaction(rt: Runtime, stamps: StageStamps, placement: Placement) -> Reaction | str:
    """Poll the stamps until the reaction is read or `WAIT_S` has passed."""
    mapping, cameras = rt.config.mapping, rt.config.sim
    voxel, range_m = mapping.edf_voxel_m, min(mapping.range_m, cameras.base_camera.range_m)
    deadline = placement.wall + WAIT_S
    result: Reaction | str = "no reaction"
    while stamps.now() < deadline:
        time.sleep(0.05)
        result = analyse(stamps, placement, voxel, range_m)
        if isinstance(result, Reaction) or result.startswith("not a reaction"):
            return result
    return result


def measure_reactions(events: int, max_wall_s: float, config: RuntimeConfig | None = None,
                      keep_s: float = 30.0) -> ReactionRun[Reaction]:
    """Live: place boxes until `events` reactions are measured (or `max_wall_s` has passed); the stamps of the
    last `keep_s` are kept."""
    rt = reaction_runtime(config)
    stamps = StageStamps(keep_s)
    rt.closed_loop.stamps = stamps
    run: ReactionRun[Reaction] = ReactionRun(stamps)
    gamma = rt.controller.params.gamma
    rt.start_live()
    rt.start()
    start = time.perf_counter()
    end = start + max_wall_s
    try:
        while len(run.events) < events and time.perf_counter() < end and rt.fault is None:
            if not cruising(rt) or not any(i.edf is not None for i in list(stamps.integrations)[-3:]):
                time.sleep(0.02)
                continue
            run.trial(place(rt, stamps), gamma, lambda p: await_reaction(rt, stamps, p),
                      lambda: rt.move_box("probe", PARK))
        run.health = loop_health(rt, stamps, time.perf_counter() - start)
    finally:
        rt.shutdown()
    return run


def loop_health(rt: Runtime, stamps: StageStamps, wall_s: float) -> dict[str, float]:
    """Control steps started more than one period late (% of steps; robot time), the 99th percentile of how late
    they started (ms), the control step's time (p95 ms, the latest `keep_s`), and the frames the map integrated per
    wall second of each camera (the mapping loop keeps only the newest frame of each camera when behind), and the
    control steps per wall second (more than the control rate where a new map triggers them)."""
    live = rt.live
    if live is None:
        return {}
    steps = max(live.control_steps, 1)
    lateness = np.asarray(live.control_lateness_s, float) * 1e3
    control_ms = [(s.wall_solve_end - s.wall_wake) * 1e3 for s in list(stamps.controls)]
    health = {"control_steps": float(live.control_steps), "control_late_pct": 100.0 * live.control.stats.late / steps,
              "control_lateness_p99_ms": float(np.percentile(lateness, 99)) if lateness.size else float("nan"),
              "control_step_p95_ms": float(np.percentile(control_ms, 95)) if control_ms else float("nan"),
              "physics_late": float(live.physics.stats.late) if live.physics is not None else float("nan")}
    health |= {f"{camera}_frames_integrated_hz": n / wall_s for camera, n in stamps.frames_integrated.items()}
    health["control_steps_hz"] = live.control_steps / wall_s
    return health
