"""`ClosedLoop`: one tick of the paper's closed loop, observe → map → control → command → measure, and the
parts it owns (map, controller, sequencer, plan, run state, fault, run log).

Lockstep calls `tick()` directly (simulated time, one thread, deterministic). Live mode
(`app/runtime/live_loops.py`) schedules the same stages on supervised threads: `observe` + `command` (I/O, 100 Hz),
`integrate_frames` (mapping, as frames arrive), `control` + `measure` (10 Hz).

Fail safe: any exception in a stage, or a non-finite robot state, calls `fault(reason)`: the robot brakes
along the plan it was following, within the acceleration limits (`core.htmpc.safety.brake_along`; from the
last command when there is no plan), the run enters `RunState.FAULT` with the reason, and `start` is refused
until the runtime is reset (which builds a new `ClosedLoop`). The emergency stop is not a fault: it
commands zero at once.

Locks, always taken in this order (never an earlier one while holding a later one):

1. `step_lock`     one control step at a time, against run control that swaps parts (start, pause and
                   resume, configure, set_sequence). Held across the sequencer and the solve; only the
                   control thread holds it for long.
2. `command_lock`  computing and sending one velocity command, against the e-stop's zero and a fault's
                   switch to braking (no stale command can follow either). Re-entrant.
3. `lock`          the run: `run_state`, `fault_reason`, `plan` and the delayed plans, `view`, `state`,
                   `timings_ms`, `latest_frames`, `last_edf`, `min_distance_m`, the step budget. Held only
                   for reads and writes: never around a solve, a map call or a backend call.
4. `map_lock`      the map (`integrate`, `local_edf`, `occupied_points`, `snapshot`, replacing it), taken
                   through `using_map`; in live mode the object and voxel maps run in their own process
                   (`isolate_map`), which serialises its own calls, and the lock only guards the swap.
5. `frames_ready`  the queue of depth frames waiting for the map (a Condition).

Locks inside the parts (`SimWorld.lock`, the bridge's `RobotLink`) and the runtime's publishing lock are
leaves: taken last and never held while calling back into the loop.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from app.map_kind import MapKind
from app.object_names import ObjectNames, map_objects
from app.runtime.components import make_controller, make_map
from app.runtime.map_process import MapProcess, MapProcessError
from app.runtime.problems import ProblemKind, ProblemLog
from app.runtime.run_log import RunLog
from app.runtime.snapshot import RunState
from app.runtime.stage_stamps import ControlStamp, FrameStamp, IntegrationStamp, StageStamps
from app.runtime.unknown_ahead import planner_points, unknown_ahead
from app.target_check import recheck_anchored
from core.errors import StudioError
from core.htmpc.safety import brake_along, braking_plan
from core.localization import LocalizationHealth, Localizer, se2
from core.localization.correction import Correction
from core.localization.lost import HOLD, INTEGRATE
from core.mapping.frame_exposure import camera_latency, frames_at_exposure
from core.mapping.reference_surface import occupied_surface, trusted_surface
from core.mapping.world_map import WorldMap
from core.params import ConstraintKind, SensorParams
from core.robot.model import RobotModel
from core.robot.state_history import StateHistory
from core.sim.simulated_backend import is_simulated
from core.sim.world import SimWorld
from core.types import (
    NQ,
    DepthFrame,
    LocalEDF,
    Observation,
    Plan,
    PlanReason,
    PlanStatus,
    PoseSource,
    References,
    ReferenceSurface,
    RobotBackend,
    RobotState,
    steps_in_lockstep,
)
from tasks.anchors import MapObjects
from tasks.schema import TaskSequence
from tasks.sequencer import Outcome, Sequencer, SubtaskProgress, plural

if TYPE_CHECKING:
    from app.runtime.config import RuntimeConfig
    from app.runtime.localization_worker import LocalizationWorker
    from core.htmpc import HTMPC

log = logging.getLogger(__name__)
T = TypeVar("T")
PROCESS_MAP_KINDS: tuple[MapKind, ...] = ("object", "voxel")
"""Maps that live mode runs in their own process (the ground-truth map reads the simulation in this one)."""
MAP_PATIENCE_S = 1.0
"""Stopping: how long to wait for a map call in flight before cutting its process short."""
MOVING_STATES = (RunState.RUNNING, RunState.FAULT)
"""Run states in which the active plan is commanded (FAULT: the braking plan)."""


class FaultError(StudioError, RuntimeError):
    """Start refused: the run is in `RunState.FAULT` (the message says why); Reset clears it."""


@dataclass(frozen=True)
class SequenceView:
    """What the sequencer shows the operator, copied after every change (the sequencer itself belongs
    to the control step)."""

    progress: tuple[SubtaskProgress, ...]
    index: int
    path: np.ndarray | None
    status: str

    @staticmethod
    def of(sequencer: Sequencer, notice: str | None = None) -> SequenceView:
        """`notice`: what slows the robot now (unknown space ahead), after the sequencer's line."""
        path = None if sequencer.path is None else sequencer.path.copy()
        status = sequencer.status_line() + (f" · {notice}" if notice else "")
        return SequenceView(tuple(sequencer.progress), sequencer.index, path, status)


@dataclass(frozen=True)
class LoopReading:
    """What the loop publishes, read at one instant under its lock (`ClosedLoop.reading`): the runtime's
    snapshot is assembled from this and the map's own snapshot, never from the loop's fields."""

    state: RobotState
    run_state: RunState
    plan: Plan | None
    view: SequenceView
    fault: str | None
    edf: LocalEDF | None
    frames: tuple[DepthFrame, ...]
    timings_ms: dict[str, float]
    min_distance_m: float
    config: RuntimeConfig
    command: np.ndarray | None
    """The last velocity command sent (None before the first)."""
    sequence: TaskSequence
    objects: MapObjects | None
    base_estimate: np.ndarray | None = None
    """The localizer's base pose [x, y, yaw] (`state.q[:3]`), None without localization."""
    base_true: np.ndarray | None = None
    """The simulator's true base pose [x, y, yaw] when the state was observed, None outside simulation."""
    localization: LocalizationHealth | None = None
    """The pose estimate's health now (`core/localization/health.py`), None without localization."""
    pose_source: PoseSource = PoseSource.ODOMETRY
    """What the backend's base pose is (its latest observation): odometry or its own localization."""


def untrusted_notice(health: LocalizationHealth | None, delta_safe_m: float) -> str | None:
    """The operator's line for an untrusted pose, with the delta_safe the controller keeps for it; None while
    the pose is trusted (or without localization)."""
    if health is None or health.untrusted is None:
        return None
    grown = (f"; delta_safe {delta_safe_m:.2f} → {delta_safe_m + health.margin_growth_m:.2f} m"
             if health.margin_growth_m >= 0.005 else "")  # said once it shows in centimetres
    return f"localization untrusted: {health.untrusted}{grown}"


def finite_state(state: RobotState) -> bool:
    return bool(np.isfinite(state.t) and np.all(np.isfinite(state.q)) and np.all(np.isfinite(state.v)))


def one_line(text: str, limit: int = 300) -> str:
    """An exception message as one line for the operator."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 1] + "…"


class ClosedLoop:
    """The robot backend, map, sequencer and controller of one run, stepped by `tick` or the live loops."""

    def __init__(self, robot: RobotModel, backend: RobotBackend, world: SimWorld | None, config: RuntimeConfig,
                 sequence: TaskSequence, notify: Callable[[str], None] = log.warning) -> None:
        self.robot, self.backend, self.world, self.config = robot, backend, world, config
        self.notify = notify
        self.step_lock = threading.Lock()
        self.command_lock = threading.RLock()
        self.lock = threading.RLock()
        self.map_lock = threading.Lock()
        self.frames_ready = threading.Condition()
        self._match_sensing()
        self.map: WorldMap = make_map(config.map_kind, robot, world, config.mapping)
        self.controller: HTMPC = make_controller(robot, config.htmpc)
        self.sequencer = self._sequencer(sequence)
        self.view = SequenceView.of(self.sequencer)
        self.run_state = RunState.IDLE
        self.fault_reason: str | None = None
        self.plan: Plan | None = None
        self._pending_plans: deque[tuple[float, Plan]] = deque()
        self._frames: deque[DepthFrame] = deque()
        self.state: RobotState = self._initial_state()
        self.base_true = self._true_base()
        """The simulator's true base pose at the last observation (None outside simulation)."""
        self.history = StateHistory(horizon_s=2.0 + config.perception_delay_s)
        """Recent states, to place each frame at its exposure (`integrate_frames`)."""
        self.last_qdot = np.zeros(NQ)
        self.commanded = False
        """Whether a command went out yet (snapshots show none before the first)."""
        self._last_command_t = -math.inf
        self.last_edf: LocalEDF | None = None
        self.last_control_wall = 0.0
        self.timings_ms: dict[str, float] = {}
        self.min_distance_m = math.nan
        self.latest_frames: dict[str, DepthFrame] = {}
        self.step_budget_s = 0.0
        self._halted_t: float | None = None
        """Robot time a running sequence was stopped or e-stopped (Start resumes with the clock moved on)."""
        self.max_plan_age_s = math.inf
        """Running on a plan from a control step older than this (robot s) is a fault (live mode sets it;
        lockstep is never late)."""
        self._last_control_t = -math.inf
        self.frames_skipped = 0
        """Live: depth frames the mapping loop skipped because it was behind (`wait_for_frames`)."""
        self._map_news: frozenset[str] = frozenset()
        """The trigger cameras (`HTMPCParams.control_trigger_cameras`) whose frames the map took since the last
        control step (replaced, never changed in place: the mapping and control threads both read it)."""
        self._triggered_t: dict[str, float] = {}
        """Robot time of the last control step each trigger camera's news went into."""
        self.log = RunLog()
        self.problems = ProblemLog(1e3 / config.htmpc.control_rate_hz)
        self.control_steps = 0
        self.unknown_slowed_steps = 0
        self._unknown_slowed = False
        """Control steps, and those slowed by unknown space ahead (`app/runtime/unknown_ahead.py`)."""
        self.localizer = self._localizer()
        self.pose_source = PoseSource.ODOMETRY
        """What the backend's base pose is (`Observation.pose_source` of its latest observation): odometry, which
        the localizer corrects (when on), or the robot's own localization, used as it is (the localizer off)."""
        self._clock_started = steps_in_lockstep(backend)
        """Whether the localizer's start is the robot's clock: a simulation's clock starts with the loop; a real
        robot's (a driver's steady clock) is taken when it first moves, not the placeholder state's 0 of a loop
        that began before the driver's first state."""
        self.localization_worker: LocalizationWorker | None = None
        """Live: the thread the registrations run on (`app/runtime/localization_worker.py`); None: they run in
        the mapping stage itself (lockstep, deterministic)."""
        self._held: deque[DepthFrame] = deque()
        """Frames waiting for a localization verdict before the map integrates them (`_confirmed_frames`)."""
        self.frames_dropped = 0
        """Frames never integrated: localization found their pose in doubt (a slip; `core/localization/lost.py`)."""
        self.held_for_search = False
        """Localization is lost: the base is held (braked to rest, no control step plans) while it searches."""
        self._search_paused = False
        """The sequencer's subtask clock was stopped for a search (`_hold_for_search`)."""
        self._untrusted = False
        """Whether the last control step found the pose untrusted (a new episode is a problem)."""
        self.untrusted_steps = 0
        """Health checks (`watch_health`) that found the pose untrusted."""
        self._surface: ReferenceSurface | None = None
        self.reference_override: Callable[[float], ReferenceSurface] | None = None
        """Benchmarks: a reference other than the map's (the true scene's surfaces, to measure registration
        apart from the map it registers against)."""
        self.names = ObjectNames(config.sequencer, config.mapping)
        self.objects_view: MapObjects | None = None
        """What the sequencer saw of the named objects at the last control step (None: nothing anchored)."""
        self.stamps: StageStamps | None = None
        """Benchmarks: wall-clock stamps of the stages (`stage_stamps.py`; None records nothing)."""

    def _match_sensing(self) -> None:
        """The simulated robot perceives through the sensor model (`SimParams.sensor`), except with the
        ground-truth map: the truth is exact, and a drifting pose estimate would misplace the robot in it."""
        if is_simulated(self.backend):
            exact = self.config.map_kind == "ground_truth"
            self.backend.set_sensor(SensorParams.ideal() if exact else self.config.sim.sensor)

    def _localizer(self) -> Localizer | None:
        """Localization (`LocalizationParams.enabled`) for a perceived map; the start pose is the world frame."""
        p = self.config.localization
        return Localizer(p, self.state.t) if p.enabled and self.config.map_kind != "ground_truth" else None

    def _true_base(self) -> np.ndarray | None:
        """The simulator's true base pose [x, y, yaw] now (what the robot does not know), None outside simulation."""
        return None if self.world is None else self.world.state().q[:3].copy()

    def _initial_state(self) -> RobotState:
        state = self.backend.observe().state  # also drops frames of an earlier scene
        if finite_state(state):
            return state
        zeros = np.zeros(NQ)
        return RobotState(state.t if np.isfinite(state.t) else 0.0, zeros, zeros.copy())

    def _sequencer(self, sequence: TaskSequence) -> Sequencer:
        p = self.controller.params
        return Sequencer(self.robot, sequence.model_copy(deep=True), self.config.sequencer, p.N, p.dt_s)

    def add_step(self, seconds: float | None = None) -> bool:
        """While paused, let the physics advance `seconds` (default one control period); False when not paused."""
        with self.lock:
            if self.run_state != RunState.PAUSED:
                return False
            self.step_budget_s += seconds or 1.0 / self.controller.params.control_rate_hz
            return True

    def set_speed(self, speed: float) -> None:
        """Sim seconds per wall second of the live loops."""
        with self.lock:
            self.config = replace(self.config, speed=float(speed))

    def reading(self) -> LoopReading:
        """What the loop publishes now, one consistent read (takes `lock`)."""
        with self.lock:
            return LoopReading(
                state=self.state, run_state=self.run_state, plan=self.plan, view=self.view, fault=self.fault_reason,
                edf=self.last_edf, frames=tuple(self.latest_frames.values()), timings_ms=dict(self.timings_ms),
                min_distance_m=self.min_distance_m, config=self.config,
                command=self.last_qdot.copy() if self.commanded else None, sequence=self.sequencer.sequence,
                objects=self.objects_view,
                base_estimate=self.state.q[:3].copy() if self.localizing else None,
                base_true=None if self.base_true is None else self.base_true.copy(),
                localization=self.health(self.state.t), pose_source=self.pose_source)

    @property
    def localizing(self) -> bool:
        """Whether the localizer is in charge of the base pose: localization on and the backend reports odometry
        (a robot that localizes itself, `PoseSource.LOCALIZED`, is used as it is)."""
        return self.localizer is not None and self.pose_source == PoseSource.ODOMETRY

    def health(self, t: float) -> LocalizationHealth | None:
        """The pose estimate's health at robot time t against the configured delta_safe (None without
        localization, and while the robot reports a pose it localized itself: the localizer is off then)."""
        localizer = self.localizer
        if localizer is None or not self.localizing:
            return None
        return localizer.health(t, self.config.htmpc.delta_safe_m)

    @property
    def moving(self) -> bool:
        """Whether the active plan is commanded now (paused, only a backend stepped in lockstep freezes: a
        real robot would keep moving, so it gets zero)."""
        paused_frozen = self.run_state == RunState.PAUSED and steps_in_lockstep(self.backend)
        return self.run_state in MOVING_STATES or paused_frozen

    # --- run control ---------------------------------------------------------------------------------

    def start(self, sequence: TaskSequence) -> None:
        """Resume the active subtask after a pause (also a stale-state one), a stop or an emergency stop;
        else (nothing begun, or the sequence finished or failed) run `sequence` from its first subtask.
        Starting over is Reset's job. FaultError while faulted."""
        with self.step_lock:
            with self.lock:
                if self.fault_reason is not None:
                    raise FaultError(f"fault: {self.fault_reason}; Reset before starting again")
                if self.run_state == RunState.RUNNING:
                    return
                if self._resumable():
                    self._resume()
                    return
            sequencer = self._sequencer(sequence)
            self.controller.reset()
            with self.lock:
                self.sequencer, self.view = sequencer, SequenceView.of(sequencer)
                self.plan = None
                self._pending_plans.clear()
                self._halted_t = None
                self.run_state = RunState.RUNNING
        log.info("sequence %r started (%s)", sequence.name, plural(len(sequence.subtasks), "subtask"))

    @property
    def under_way(self) -> bool:
        """A run is under way: running, or interrupted mid-sequence so that Start resumes it."""
        with self.lock:
            return self._under_way()

    def _under_way(self) -> bool:
        return self.run_state == RunState.RUNNING or self._resumable()

    def _resumable(self) -> bool:
        """Whether Start resumes: the run was interrupted (paused, stopped, e-stopped) with a subtask begun
        and the sequence neither finished nor failed (call under `lock`)."""
        if self.run_state == RunState.PAUSED:
            return True
        begun = any(p.outcome != Outcome.PENDING for p in self.sequencer.progress)
        return (self.run_state in (RunState.IDLE, RunState.ESTOP) and begun and not self.sequencer.failed
                and not self.sequencer.finished)

    def _resume(self) -> None:
        """Run the active subtask on (under `step_lock` and `lock`); the interruption counts toward neither its
        timeout nor its dwell."""
        interrupted = self.run_state
        if self._halted_t is not None:  # stopped or e-stopped: the subtask clock stood still since then
            self.sequencer.pause(self._halted_t)
        self.sequencer.resume()  # from the next state's time: the robot's clock may have run on unseen
        if not steps_in_lockstep(self.backend) or interrupted != RunState.PAUSED:  # a robot held still: plan void
            self.plan = None
            self._pending_plans.clear()
        self._last_control_t = self.state.t  # the interruption is no lateness of the control loop
        self._halted_t = None
        self.run_state = RunState.RUNNING
        if interrupted != RunState.PAUSED:
            log.info("sequence resumed at subtask %d after %s", self.sequencer.index + 1, interrupted.value)

    def pause(self) -> None:
        with self.step_lock, self.lock:
            if self.run_state in (RunState.RUNNING, RunState.IDLE):
                self.run_state = RunState.PAUSED
                self.sequencer.pause(self.state.t)

    def halt(self, run_state: RunState) -> None:
        """Enter `run_state`, drop the plan and any delayed ones, command zero velocity now."""
        with self.command_lock:
            with self.lock:
                if run_state != RunState.FAULT and self.run_state == RunState.RUNNING:
                    self._halted_t = self.state.t  # the subtask clock stands still until Start resumes
                self.run_state = run_state
                self.plan = None
                self._pending_plans.clear()
                t = self.state.t
            self.last_qdot = np.zeros(NQ)
            self.backend.command(self.last_qdot.copy(), t)

    def stop(self) -> None:
        """Stop the sequence (zero command); while faulted, the robot goes on braking within its limits."""
        if self.fault_reason is None:
            self.halt(RunState.IDLE)

    def skip(self) -> bool:
        """Skip the active subtask (running or paused): the sequence goes on with the next one; False when no
        subtask is active."""
        with self.step_lock, self.lock:
            if self.run_state not in (RunState.RUNNING, RunState.PAUSED) or not self.sequencer.skip(self.state.t):
                return False
            self.view = SequenceView.of(self.sequencer)
            return True

    def set_sequence(self, sequence: TaskSequence) -> None:
        """A new authored sequence: shown at once unless a run is under way (`under_way`: running, or paused,
        stopped or e-stopped mid-sequence, which Start resumes): that run keeps its copy to the end."""
        with self.step_lock, self.lock:
            if not self._under_way():
                self.sequencer = self._sequencer(sequence)
                self.view = SequenceView.of(self.sequencer)

    def configure(self, map_kind: MapKind | None, constraint: ConstraintKind | None) -> None:
        """Swap the map (empty) and/or the controller; takes effect at the next control step."""
        with self.step_lock:
            with self.lock:
                self.config = self.config.configured(map_kind or None, constraint or None)
            if map_kind:
                self._match_sensing()
                new_map = make_map(self.config.map_kind, self.robot, self.world, self.config.mapping)
                with self.map_lock:
                    old, self.map = self.map, new_map
                if isinstance(old, MapProcess):
                    self.isolate_map(old)  # the new map runs in the same worker
            if constraint:
                controller = make_controller(self.robot, self.config.htmpc)
                controller.enforce_timeout = self.controller.enforce_timeout
                with self.lock:
                    self.controller = controller

    def isolate_map(self, process: MapProcess | None = None, niceness: int | None = None) -> None:
        """Live: run an object or voxel map in its own process (app/runtime/map_process.py), so that its CPU work
        never holds the GIL the I/O and control loops need; in `process` (still running) if given, else in a
        new one at `niceness` (default: `map_process.NICENESS` below the calling thread's priority)."""
        with self.map_lock:
            if self.config.map_kind not in PROCESS_MAP_KINDS or isinstance(self.map, MapProcess):
                if process is not None:
                    process.close(keep=False)
                return
            if process is not None:
                try:
                    process.adopt(self.map)
                    self.map = process
                    return
                except MapProcessError as err:
                    log.warning("a new mapping process instead: %s", err)
                    process.close(keep=False)
            self.map = MapProcess(self.map, niceness=niceness)

    def release_map(self) -> MapProcess | None:
        """Reset: the isolated map's process, to run the next loop's map (None if there is none)."""
        with self.map_lock:
            process = self.map
            return process if isinstance(process, MapProcess) and process.alive else None

    def restore_map(self, keep: bool = True) -> None:
        """End an isolated map's process, bringing the map back into this one (with `keep`; else, or if it
        cannot be handed back, a fresh map). A call stuck on the process is cut short."""
        with self.map_lock:
            isolated = self.map
            if not isinstance(isolated, MapProcess):
                return
            world_map = isolated.close(keep, patience_s=MAP_PATIENCE_S)
            self.map = world_map or make_map(self.config.map_kind, self.robot, self.world, self.config.mapping)

    @contextlib.contextmanager
    def using_map(self) -> Iterator[WorldMap]:
        """The map for a call, under the map lock; an isolated map serialises its own calls and answers
        queries from what its latest integration brought back, so then the lock is not held (control
        never waits for an integration in progress)."""
        with self.map_lock:
            world_map = self.map
            if not getattr(world_map, "serialises_calls", False):
                yield world_map
                return
        yield world_map

    def take_physics_step(self, dt: float) -> bool:
        """Live physics: whether to advance by dt now (not while paused, unless `step` granted time)."""
        with self.lock:
            if self.run_state != RunState.PAUSED:
                return True
            if self.step_budget_s <= 1e-9:
                return False
            self.step_budget_s -= dt
            return True

    # --- faults --------------------------------------------------------------------------------------

    def fault(self, reason: str) -> None:
        """Brake along the commanded plan within the acceleration limits and hold the run in FAULT.

        The first reason stands until reset; never raises (it is what the loops call when they fail)."""
        reason = one_line(reason)
        try:
            with self.command_lock, self.lock:
                if self.fault_reason is not None:
                    return
                self.plan = self._braking_plan(self.state.t)  # along the plan commanded last (not a newer one)
                self._pending_plans.clear()
                self.run_state = RunState.FAULT
                self.fault_reason = reason  # last: whoever sees the reason sees the FAULT state
                self.log.event(self.state.t, "fault", reason)
                self.problems.record(ProblemKind.FAULT, self.state.t, reason)
        except Exception:  # the fault must hold even if braking could not be planned: zero is all that is left
            log.exception("planning the fault brake failed")
            with self.lock:
                self.plan, self.run_state, self.fault_reason = None, RunState.FAULT, reason
            self.problems.record(ProblemKind.FAULT, self.state.t, reason)
        self.notify(f"fault: {reason}: braking to a stop within the limits; Reset to go on")

    def _braking_plan(self, t: float, why: str = "fault", reason: PlanReason = PlanReason.FAULT) -> Plan:
        """The commanded plan slowed to a stop along its path within a_max; without one (or when it cannot
        be followed), every joint ramps down from the last command within a_max. `why` heads the plan's message,
        `reason` is its `PlanReason` (a fault's brake counts as one; a hold while lost does not)."""
        lim, p = self.robot.limits, self.controller.params
        plan = None
        if self.plan is not None and self.moving:
            plan = brake_along(self.plan, t, lim, p.N, p.dt_s, PlanStatus.STOPPING, f"{why}: braking along the plan",
                               reason)
        if plan is None:
            last = RobotState(t, self.state.q, np.asarray(self.last_qdot, float))
            plan = braking_plan(last, lim, p.N, p.dt_s, PlanStatus.STOPPING, f"{why}: braking", reason=reason)
        return plan

    def guarded(self, stage: str, fn: Callable[..., T], *args) -> T | None:
        """`fn(*args)`; an exception of any kind becomes a fault naming `stage` (None is returned)."""
        try:
            return fn(*args)
        except Exception as err:
            if self.fault_reason is None:  # the operator gets one line (fault); the traceback is for debugging
                log.debug("%s failed", stage, exc_info=True)
            self.fault(f"{stage}: {type(err).__name__}: {err}")
            return None

    def braked(self) -> bool:
        """Whether a faulted run has come to rest (its braking plan ended and the command is zero)."""
        with self.lock:
            plan, t = self.plan, self.state.t
        ended = plan is None or t >= plan.t + plan.dt * plan.u.shape[0] or not np.any(plan.velocity_at(t))
        return self.fault_reason is not None and ended and not np.any(self.last_qdot)

    # --- the stages ----------------------------------------------------------------------------------

    def observe(self, dt_hint_s: float) -> RobotState:
        """Latest robot state and frames. A non-finite state is a fault: the last finite state is kept (its
        time advanced by `dt_hint_s` when the time itself is not finite) and the frames are dropped."""
        obs: Observation = self.backend.observe()
        state = obs.state
        if not finite_state(state):
            previous = self.state
            t = float(state.t) if np.isfinite(state.t) else previous.t + dt_hint_s
            with self.lock:
                self.state = RobotState(t, previous.q, previous.v)
            self.fault(f"non-finite robot state at t = {t:.2f} s")
            return self.state
        true_base = self._true_base()
        frames = obs.frames
        self._follow_pose_source(obs.pose_source, state.t)
        if self.localizing:
            state, frames = self._reposed(state, frames)
        if frames and self.fault_reason is None:
            with self.frames_ready:
                self._frames.extend(frames)
                self.frames_ready.notify()
        with self.lock:
            self.state = state
            self.base_true = true_base
            self.history.append(state)
        return state

    def _follow_pose_source(self, source: PoseSource, t: float) -> None:
        """Take the backend's pose source of this observation. A robot that switches to its own localization is
        used as it is from now on; one that switches back to odometry gets a new localizer (its odometry frame is
        not the world its localization reported in). The localizer's clock starts when the robot's does
        (`_clock_started`)."""
        if self.localizer is not None and not self._clock_started and t != self.state.t:
            self._clock_started = True
            self.localizer.start_t = t
        if source == self.pose_source:
            return
        with self.lock:
            self.pose_source = source
            self._untrusted = False  # an episode of the localizer's ends with its charge
        if self.localizer is None:
            return
        if source == PoseSource.LOCALIZED:
            message = "the robot reports a pose it localized itself: used as it is, the localizer is off for it"
        else:
            self.localizer = Localizer(self.config.localization, t)
            message = "the robot reports odometry again: the localizer corrects it, starting afresh"
        self.log.event(t, "pose_source", source.value)
        self.notify(message)

    def _reposed(self, state: RobotState, frames: tuple[DepthFrame, ...]
                 ) -> tuple[RobotState, tuple[DepthFrame, ...]]:
        """The backend's odometry-frame state and frames in the world: T_world←odom after the odometry's
        prediction and the corrections due by now (`core/localization`)."""
        assert self.localizer is not None
        self.localizer.predict(state.q[:3], state.t)
        self.localizer.apply_due(state.t)
        T = self.localizer.world_from_odom
        q, v = state.q.copy(), state.v.copy()
        q[:2] = se2.compose(T, state.q[:3])[:2]
        q[2] = state.q[2] + T[2]  # a joint: never wrapped (the controller needs it continuous)
        v[:2] = se2.rot(float(T[2])) @ state.v[:2]
        T4 = se2.to_matrix(T)
        return RobotState(state.t, q, v), tuple(replace(f, T_world_camera=T4 @ f.T_world_camera) for f in frames)

    def _to_odometry(self, qdot: np.ndarray) -> np.ndarray:
        """A world-frame command in the backend's odometry frame."""
        localizer = self.localizer
        if localizer is None or not self.localizing:
            return qdot
        out = qdot.copy()
        out[:2] = se2.rot(-float(localizer.world_from_odom[2])) @ qdot[:2]
        return out

    def localize(self, frames: tuple[DepthFrame, ...]) -> None:
        """Register the frames localization wants (at their exposure, posed by the current estimate) against
        the map's trusted surfaces; hand the objects that disagreed to the map as change evidence; watch the
        pose's health (`watch_health`). Live, the registrations run on the localization worker's thread
        (`localization_worker`: handed over here, never waited for); lockstep, here and now (deterministic)."""
        localizer = self.localizer
        if localizer is None or not self.localizing:
            return
        worker = self.localization_worker
        if worker is not None:
            worker.submit([(f, self._base_at(f.t)) for f in frames if localizer.wants(f)])
            return
        for frame in frames:
            if localizer.wants(frame):  # asked frame by frame: a registration makes the next frames unwanted
                self.register(frame, self._base_at(frame.t))
        self.after_registrations()

    def _base_at(self, t: float) -> np.ndarray:
        """The base pose at robot time t (a frame's exposure: the frames are already moved back to it)."""
        with self.lock:
            exposure = self.history.at(t)
            return (exposure or self.state).q[:3].copy()

    def register(self, frame: DepthFrame, base: np.ndarray) -> Correction | None:
        """One registration of `frame` (the base at `base` at its exposure) against the map's trusted surfaces
        (`Localizer.correct`: the slow part); its correction becomes due at the frame's stamp plus the modelled
        processing time, applied by `observe`. None while the localizer is off."""
        localizer = self.localizer
        if localizer is None or not self.localizing:
            return None
        return localizer.correct(frame, base, self._reference_surface(frame.t))

    def after_registrations(self) -> None:
        """Watch the pose's health now; hand the objects the registrations found disagreeing to the map as change
        evidence."""
        with self.lock:
            now = self.state.t
        self._answer_lost(now)
        self.watch_health(now)
        localizer = self.localizer
        evidence = localizer.take_change_evidence() if localizer is not None else ()
        if evidence:
            with self.using_map() as world_map:
                note = getattr(world_map, "note_change_evidence", None)
                if note is not None:
                    note(evidence)

    def _answer_lost(self, t: float) -> None:
        """The loop's answer to the localizer's lost state (`core/localization/lost.py`): lost, the base is held
        (braking to rest within the limits, no control step plans) and the operator told; found again, control plans
        from the re-anchored pose; given up, the run faults with "lost localization"."""
        localizer = self.localizer
        if localizer is None:
            return
        with localizer.lock:
            lost, failed = localizer.lost.lost, localizer.lost.failed
        if failed is not None:
            self.fault(failed)
            return
        if lost and not self.held_for_search:
            with self.command_lock, self.lock:
                self.held_for_search = True
                if self.fault_reason is None:
                    self.plan = self._braking_plan(self.state.t, "localization lost: holding the base",
                                                    PlanReason.NONE)
                    self._pending_plans.clear()
                self._untrusted = False  # a new untrusted episode, whatever came before: `watch_health` records it
        elif not lost and self.held_for_search:
            with self.lock:
                self.held_for_search = False
            self.notify("localization found again: re-anchored, the run goes on")

    def _reference_surface(self, t: float) -> ReferenceSurface:
        """The map's trusted surfaces, asked for at most every `reference_period_s` (the map's lock is held only
        to read the map, not while the surface is sampled from it)."""
        p = self.config.localization
        if self._surface is None or t >= self._surface.t + p.reference_period_s:
            if self.reference_override is not None:
                self._surface = self.reference_override(t)
                return self._surface
            with self.using_map() as world_map:
                snap = world_map.snapshot()
                occupied = None if snap.objects else world_map.occupied_points()
            surface = (trusted_surface(snap, p.trust_consistency, p.trust_observations) if occupied is None
                       else occupied_surface(t, occupied))
            self._surface = replace(surface, t=t)
        return self._surface

    def camera_latency_s(self) -> float:
        """The calibrated exposure-to-stamp latency (`MappingParams.camera_latency_s`); unset, the one the
        backend declares (`BackendAbilities.camera_latency_s`: the simulated camera's own offset)."""
        return camera_latency(self.config.mapping.camera_latency_s, self.backend.abilities.camera_latency_s)

    def advance_clock(self, dt_s: float) -> RobotState:
        """No observation this period (the backend raised): keep the last state, its time moved on by dt_s,
        so a braking plan still runs down."""
        with self.lock:
            self.state = replace(self.state, t=self.state.t + dt_s)
            return self.state

    def wait_for_frames(self, timeout_s: float) -> bool:
        """Live mapping: wait for frames; when behind, keep only the newest frame of each camera, and count each
        frame skipped as a problem (the camera's rate is not kept: say so rather than map at a slower rate)."""
        with self.frames_ready:
            if not self._frames:
                self.frames_ready.wait(timeout=timeout_s)
            if not self._frames:
                return False
            newest: dict[str, DepthFrame] = {}
            skipped: dict[str, int] = {}
            for f in self._frames:
                if f.camera in newest:
                    skipped[f.camera] = skipped.get(f.camera, 0) + 1
                newest[f.camera] = f
            self._frames.clear()
            self._frames.extend(sorted(newest.values(), key=lambda f: f.t))
        if skipped:
            self._frames_skipped(skipped, max(f.t for f in newest.values()))
        return True

    def _frames_skipped(self, skipped: dict[str, int], t: float) -> None:
        for camera, n in skipped.items():
            self.frames_skipped += n
            self.problems.record(ProblemKind.FRAMES_SKIPPED, t,
                                 f"the map fell behind the {camera} camera: {plural(n, 'frame')} skipped "
                                 f"({self.frames_skipped} in all; only the newest is integrated)")

    def wake_mapping(self) -> None:
        with self.frames_ready:
            self.frames_ready.notify_all()

    def integrate_frames(self, now: float) -> None:
        """Give the map every queued frame older than the modelled perception delay (none while faulted)."""
        with self.frames_ready:
            due = []
            while self._frames and self._frames[0].t <= now - self.config.perception_delay_s + 1e-9:
                due.append(self._frames.popleft())
        if not due or self.fault_reason is not None:
            return
        with self.lock:
            frames, state = self._at_exposure(due)
            for frame in frames:  # the studio's clouds too, where the camera was
                self.latest_frames[frame.camera] = frame
        held = self.localizer is not None and self.config.localization.hold_frames
        if held:  # registered first: frames wait for a verdict, and never go in at a pose that has jumped
            frames, state = self._confirmed_frames(frames)
            if not frames:
                return
        t0 = time.perf_counter()
        with self.using_map() as world_map:
            world_map.integrate(Observation(state=state, frames=frames, odometry=None))
        t1 = time.perf_counter()
        with self.lock:
            self.timings_ms["mapping"] = (t1 - t0) * 1e3
        if self.stamps is not None:
            self._stamp_integration(world_map, frames, t0, t1)
        if not held:
            self.localize(frames)
        p = self.controller.params
        if p.control_on_new_map:
            self._map_news |= {f.camera for f in frames if f.camera in p.control_trigger_cameras}

    def _confirmed_frames(self, frames: tuple[DepthFrame, ...]) -> tuple[tuple[DepthFrame, ...], RobotState]:
        """Localization first (`localize`), then the frames (these and those held before) whose pose a verdict has
        confirmed, with the state at the newest one's exposure; frames not confirmed yet wait, and those at a pose
        that may have jumped are dropped (`core/localization/lost.py`, `LocalizationParams.hold_frames`)."""
        localizer = self.localizer
        assert localizer is not None
        self.localize(frames)
        with self.lock:
            now = self.state.t
        self._held.extend(frames)
        ready, waiting = [], deque()
        with localizer.lock:
            for frame in self._held:
                fate = localizer.lost.fate(frame.t, now)
                if fate == INTEGRATE:
                    ready.append(frame)
                elif fate == HOLD:
                    waiting.append(frame)
                else:
                    self.frames_dropped += 1
        self._held = waiting
        with self.lock:
            state = self.history.at(max(f.t for f in ready)) if ready else None
        return tuple(ready), state if state is not None else self.state

    def control_triggered(self, t: float) -> bool:
        """Whether the map has taken frames that call for a control step now (`HTMPCParams.control_on_new_map`):
        new frames of a camera of `control_trigger_cameras` since the last step, at least 1 / `control_max_rate_hz` of
        robot time after the last step that camera's news went into (until then its news waits). Per camera, so two
        cameras at different phases do not hold each other's frames back; the steps a second stay within the
        cameras' rates, each capped at `control_max_rate_hz`."""
        spacing = 1.0 / self.controller.params.control_max_rate_hz
        return any(t + 1e-9 >= self._triggered_t.get(c, -math.inf) + spacing for c in self._map_news)

    def _stamp_integration(self, world_map: WorldMap, frames: tuple[DepthFrame, ...], t0: float, t1: float) -> None:
        """Record an integration (benchmarks): its frames, wall span, and the EDF an isolated map built after it."""
        assert self.stamps is not None
        latency = self.camera_latency_s()
        latest = getattr(world_map, "latest_edf", None)
        edf, ready = latest if latest is not None else (None, t1)
        edf_ms = float(world_map.timings_ms.get("edf", 0.0)) if edf is not None else 0.0
        self.stamps.integration(IntegrationStamp(tuple(FrameStamp.of(f, latency) for f in frames), t0,
                                                         min(ready, t1), edf, edf_ms))

    def _at_exposure(self, frames: list[DepthFrame]) -> tuple[tuple[DepthFrame, ...], RobotState]:
        """The frames moved back to their exposure (camera latency compensated, `frames_at_exposure`) and the
        robot's state at the newest exposure: the map places the robot's body there, not where it is now (call
        under `lock`)."""
        moved = frames_at_exposure(frames, self.history, self.camera_latency_s(), self.robot)
        newest = self.history.at(max(f.t for f in moved))
        return moved, newest if newest is not None else self.state

    def control(self, state: RobotState) -> None:
        """Sequencer → references → HTMPC; the plan becomes active after the modelled actuation delay."""
        t0 = time.perf_counter()
        news, self._map_news = self._map_news, frozenset()  # this step plans on the map as it is now
        for camera in news:
            self._triggered_t[camera] = state.t
        with self.step_lock:
            with self.lock:
                if self.run_state != RunState.RUNNING:
                    return
                sequencer, controller = self.sequencer, self.controller
            if self._hold_for_search(state.t, sequencer):
                with self.lock:  # holding the base is this step's decision, not a control loop gone quiet
                    self._stamp_control_step(state.t)
                return
            with self.using_map() as world_map:
                occupied = world_map.occupied_points()
                t_edf = time.perf_counter()
                edf = world_map.local_edf(state.q[:2])
                t_edf_end = time.perf_counter()
                edf_ms = (t_edf_end - t_edf) * 1e3
                objects = map_objects(self.names, world_map, sequencer.sequence, self.world, state.t)
            refs = sequencer.update(state, planner_points(occupied, edf), state.t, objects)
            self._tell_anchor_moves(sequencer, objects, state.t)
            notice = self._unknown_notice(state, refs, edf)
            self._answer_health(state.t, controller, sequencer)
            plan, solve_ms = None, math.nan
            t_solve = t_solved = time.perf_counter()
            if refs is not None:
                plan = controller.solve(state, refs, edf)
                t_solved = time.perf_counter()
                solve_ms = (t_solved - t_solve) * 1e3
                self.problems.observe_plan(plan, state.t, solve_ms)
            if self.stamps is not None:
                self.stamps.controls.append(ControlStamp(state.t, t0, t_edf_end, t_solve, t_solved, edf, plan))
            with self.lock:
                self.last_edf, self.view, self.objects_view = edf, SequenceView.of(sequencer, notice), objects
                self.timings_ms["edf"] = edf_ms
                if self.run_state != RunState.RUNNING:  # stopped, e-stopped or faulted during the step
                    return
                if plan is None:
                    self.run_state = RunState.FAILED if sequencer.failed else RunState.FINISHED
                    self.plan = None
                    self._pending_plans.clear()
                else:
                    self.timings_ms["solve"] = solve_ms
                    self._pending_plans.append((state.t + self.config.actuation_delay_s, plan))
                    self._stamp_control_step(state.t)
        if plan is None and sequencer.failed:
            self.notify(sequencer.status_line())
        with self.lock:
            self.timings_ms["control"] = (time.perf_counter() - t0) * 1e3

    def _stamp_control_step(self, t: float) -> None:
        """A control step ran at robot time t: the age `_command_at` holds the plan against starts again (call under
        `lock`)."""
        self.last_control_wall = time.time()
        self._last_control_t = t

    def _hold_for_search(self, t: float, sequencer: Sequencer) -> bool:
        """Whether this control step plans nothing because localization is lost (the subtask's clock stands still
        meanwhile and runs on once found again; call under `step_lock`)."""
        if self.held_for_search:
            if not self._search_paused:
                sequencer.pause(t)
                self._search_paused = True
            return True
        if self._search_paused:
            sequencer.resume(t)
            self._search_paused = False
        return False

    def refresh_objects_view(self) -> None:
        """The named objects as the sequencer will see them, now (a name given while paused shows at once; call
        under `step_lock`)."""
        with self.using_map() as world_map:
            objects = map_objects(self.names, world_map, self.sequencer.sequence, self.world, self.state.t)
        with self.lock:
            self.objects_view = objects

    def _unknown_notice(self, state: RobotState, refs: References | None, edf: LocalEDF | None) -> str | None:
        """Unknown space slowing the base now: counted, and a new episode recorded as a problem."""
        p = self.controller.params
        notice = unknown_ahead(state, refs, edf, self.robot.params.base_size_m[0] / 2, p.delta_safe_m,
                               self.robot.limits.v_max[0] / p.gamma)
        self.control_steps += 1
        if notice is not None:
            self.unknown_slowed_steps += 1
            if not self._unknown_slowed:
                self.problems.record(ProblemKind.UNKNOWN_SPACE, state.t, notice)
        self._unknown_slowed = notice is not None
        return notice

    def _answer_health(self, t: float, controller: HTMPC, sequencer: Sequencer) -> None:
        """The controller's answer to the pose's health at this control step: delta_safe grown by its uncertainty
        (`LocalizationParams.grow_margin`; zero growth while σ is small); an untrusted pose is also watched here
        (call under `step_lock`)."""
        health = self.watch_health(t)
        if self.localizer is not None:  # no growth while the robot localizes itself (no health of ours then)
            growth = health.margin_growth_m if health else 0.0
            controller.set_delta_safe(self.config.htmpc.delta_safe_m + growth)
            sequencer.set_margin_growth(growth)  # the planner's paths keep the clearance the controller keeps

    def watch_health(self, t: float) -> LocalizationHealth | None:
        """The pose's health at robot time t; a new untrusted episode is recorded as a problem (once) and told to
        the operator. Called after every integration (`localize`) and control step, so a run that stands still
        or has finished is watched too."""
        health = self.health(t)
        if health is None:
            return None
        with self.lock:
            was, self._untrusted = self._untrusted, health.untrusted is not None
        if health.untrusted is not None:
            self.untrusted_steps += 1
            if not was:
                notice = untrusted_notice(health, self.config.htmpc.delta_safe_m)
                assert notice is not None
                self.problems.record(ProblemKind.LOCALIZATION, t, notice)
                self.notify(notice)
        return health

    def _tell_anchor_moves(self, sequencer: Sequencer, objects: MapObjects | None, t: float) -> None:
        """An anchored target followed its object: tell the operator, and check the target again there (an
        unreachable one is a problem with its reason)."""
        notices = sequencer.take_notices()
        for notice in notices:
            self.notify(notice)
        for reason in recheck_anchored(self, sequencer.sequence, sequencer.index, objects) if notices else []:
            self.problems.record(ProblemKind.ANCHORED_TARGET, t, reason)
            self.notify(reason)

    def _activate_due(self, t: float) -> None:
        while self._pending_plans and self._pending_plans[0][0] <= t + 1e-9:
            self.plan = self._pending_plans.popleft()[1]

    def command(self, t: float) -> np.ndarray:
        """Send the velocity command at robot time t from the active plan (zero when none or not moving);
        a non-finite command is a fault, and the braking plan's command goes out instead."""
        with self.command_lock:
            t = max(t, self._last_command_t)  # robot time of commands never runs backwards
            self._last_command_t = t
            qdot, plan = self._command_at(t)
            if not np.all(np.isfinite(qdot)):
                self.fault("non-finite command from the plan")
                qdot, plan = self._command_at(t)
                qdot = qdot if np.all(np.isfinite(qdot)) else np.zeros(NQ)
            qdot = self.robot.limits.clip_velocity(qdot)
            self.last_qdot = qdot
            self.commanded = True
            self.backend.command(self._to_odometry(qdot), t)
            if self.stamps is not None:
                self.stamps.command(t, qdot, plan)
        return qdot

    def _command_at(self, t: float) -> tuple[np.ndarray, Plan | None]:
        """The velocity of the active plan at t (zero without one), and that plan."""
        with self.lock:
            self._activate_due(t)
            plan = self.plan if self.moving else None
            age = t - self._last_control_t
            late = self.run_state == RunState.RUNNING and plan is not None and age > self.max_plan_age_s
        if late:
            self.fault(f"control is late: no control step for {age:.1f} s")
            with self.lock:
                plan = self.plan
        return (plan.velocity_at(t) if plan is not None else np.zeros(NQ)), plan

    def measure(self, qdot: np.ndarray) -> None:
        """One row of the run log (at the control rate), with the robot–box distance in simulation."""
        distance = self.world.robot_box_distance()[0] if self.world is not None else math.nan
        with self.lock:
            self.min_distance_m = distance
            row = (self.state, self.plan, self.run_state, self.view.index, dict(self.timings_ms))
        collisions = len(self.world.collisions) if self.world is not None else 0
        state, plan, run_state, index, timings = row
        self.log.record(state, plan, distance, collisions, run_state, index, qdot, timings)

    # --- lockstep ------------------------------------------------------------------------------------

    def tick(self, dt_s: float, control: bool, after_control: Callable[[], None] | None = None) -> bool:
        """One command period: observe → map → control (when `control` is due, or the map's new frames trigger
        it: `control_triggered`) → command → measure; whether a control step ran.

        Every stage is guarded: an exception faults the run and the remaining stages still run, so the
        braking command goes out. `after_control` runs after the control stage (not guarded)."""
        state = self.guarded("observe", self.observe, dt_s) or self.advance_clock(dt_s)
        self.guarded("mapping", self.integrate_frames, state.t)
        control = control or self.control_triggered(state.t)
        if control:
            self.guarded("control", self.control, state)
            if after_control is not None:
                after_control()
        qdot = self.guarded("command", self.command, state.t)
        qdot = np.zeros(NQ) if qdot is None else qdot
        if control:
            self.guarded("measure", self.measure, qdot)
        return control
