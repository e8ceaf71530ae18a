"""The closed loop of the paper: robot backend, map, sequencer and HTMPC, in two modes.

- **lockstep** (`run_lockstep`): simulated time, one thread, deterministic, as fast as the machine
  allows; optional modelled perception and actuation delays. For tests, reports and benchmarks.
- **live** (`start`): wall-clock threads that never block one another: physics (simulation only),
  I/O at 100 Hz (observe, command), mapping as frames arrive, control at 10 Hz, publishing at 20 Hz.

Rates (paper): physics 500 Hz, depth 10 Hz, HTMPC 10 Hz, velocity commands 100 Hz interpolated from
the latest plan (`Plan.velocity_at`). The runtime is the only owner of these parts; the UI and the
bridge read `Snapshot`s and call the public methods below.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.components import make_controller, make_map
from app.run_log import RunLog
from app.snapshot import EDFSlice, RunState, Snapshot
from core.params import HTMPCParams, MappingParams, SensorParams, SequencerParams, SimParams
from core.robot.model import RobotModel
from core.sim.scene import Box, Scene, load_scene, random_scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import DepthFrame, LocalEDF, Plan, RobotBackend, RobotState
from tasks.schema import TaskSequence
from tasks.sequence_file import load_sequence
from tasks.sequencer import Outcome, Sequencer

log = logging.getLogger(__name__)

ROOT = Path(__file__).parents[1]
DEFAULT_SCENE = ROOT / "core" / "sim" / "scenes" / "default.yaml"
DEFAULT_SEQUENCE = ROOT / "tasks" / "examples" / "two_pickups.yaml"
MAP_KINDS = ("object", "voxel", "ground_truth")
EDF_SLICE_Z_M = 0.3


@dataclass(frozen=True)
class RuntimeConfig:
    """How to run: scene, sequence, map and constraint kind, pace, modelled delays, tunables."""

    scene: Path | None = DEFAULT_SCENE
    sequence: Path | None = DEFAULT_SEQUENCE
    map_kind: str = "object"
    constraint: str = "cbf"
    speed: float = 1.0
    """Live mode: sim seconds per wall second."""
    perception_delay_s: float = 0.0
    actuation_delay_s: float = 0.0
    publish_hz: float = 20.0
    seed: int = 0
    htmpc: HTMPCParams = field(default_factory=HTMPCParams)
    mapping: MappingParams = field(default_factory=MappingParams)
    sequencer: SequencerParams = field(default_factory=SequencerParams)
    sim: SimParams = field(default_factory=SimParams)

    def __post_init__(self) -> None:
        if self.map_kind not in MAP_KINDS:
            raise ValueError(f"map_kind must be one of {MAP_KINDS}, got {self.map_kind!r}")
        if self.constraint not in ("cbf", "edf"):
            raise ValueError(f"constraint must be 'cbf' or 'edf', got {self.constraint!r}")
        if not (0.05 <= self.speed <= 20.0):
            raise ValueError(f"speed must be within 0.05–20, got {self.speed}")


class Runtime:
    """Owns the robot backend, world (simulation), map, sequencer and controller."""

    def __init__(self, config: RuntimeConfig | None = None, scene: Scene | None = None,
                 sequence: TaskSequence | None = None, backend: RobotBackend | None = None) -> None:
        self.config = config or RuntimeConfig()
        self.robot = RobotModel()
        self._lock = threading.RLock()
        self._map_lock = threading.Lock()
        self._scene = scene or (load_scene(self.config.scene) if self.config.scene else Scene())
        if backend is None:
            self.world: SimWorld | None = SimWorld(self.robot, self.config.sim, self._scene)
            self.backend: RobotBackend = SimRobot(self.world, seed=self.config.seed)
        else:
            self.world, self.backend = None, backend
            if self.config.map_kind == "ground_truth":
                raise ValueError("the ground-truth map needs the embedded simulation")
        self.sequence = sequence or (load_sequence(self.config.sequence) if self.config.sequence else TaskSequence())
        self.sequence_version = 0
        self.run_state = RunState.IDLE
        self.log = RunLog()
        self._subscribers: list[Callable[[Snapshot], None]] = []
        self._messages: deque[str] = deque(maxlen=20)
        self._threads: list[threading.Thread] = []
        self._stop_threads = threading.Event()
        self._step_budget_s = 0.0
        self._seq = 0
        self._frames: deque[DepthFrame] = deque()
        self._frames_ready = threading.Condition()
        self._pending_plans: deque[tuple[float, Plan]] = deque()
        self._build_parts()

    # --- parts -----------------------------------------------------------------------------------

    def _build_parts(self) -> None:
        cfg = self.config
        htmpc = replace(cfg.htmpc, constraint=cfg.constraint)
        self._match_sensing()
        self.map = make_map(cfg.map_kind, self.robot, self.world, cfg.mapping)
        self.controller = make_controller(self.robot, htmpc)
        self.sequencer = Sequencer(self.robot, self.sequence, cfg.sequencer, htmpc.N, htmpc.dt_s)
        self.plan: Plan | None = None
        self.state: RobotState = self.backend.observe().state
        self.last_edf: LocalEDF | None = None
        self.last_control_wall = 0.0
        self.timings_ms: dict[str, float] = {}
        self.min_distance_m = math.nan
        self.latest_frames: dict[str, DepthFrame] = {}

    def _match_sensing(self) -> None:
        """The simulated robot perceives through the sensor model (`SimParams.sensor`), except with the
        ground-truth map: the truth is exact, and a drifting pose estimate would misplace the robot in it."""
        if isinstance(self.backend, SimRobot):
            exact = self.config.map_kind == "ground_truth"
            self.backend.set_sensor(SensorParams.ideal() if exact else self.config.sim.sensor)

    @property
    def time(self) -> float:
        return self.state.t

    # --- subscribers ---------------------------------------------------------------------------

    def subscribe(self, callback: Callable[[Snapshot], None]) -> Callable[[], None]:
        """Call `callback(snapshot)` on every publish; returns a function that unsubscribes."""
        self._subscribers.append(callback)
        return lambda: self._subscribers.remove(callback) if callback in self._subscribers else None

    def notify(self, message: str) -> None:
        """Queue an operator-facing message (error or warning) for the next snapshot."""
        log.warning(message)
        self._messages.append(message)

    def snapshot(self, consume_messages: bool = False) -> Snapshot:
        """The current state of everything, as one value (`publish` hands the queued messages on)."""
        with self._lock:
            self._seq += 1
            with self._map_lock:
                object_map = self.map.snapshot()
                points = self.map.occupied_points()
            if len(points) > 20000:
                points = points[:: int(math.ceil(len(points) / 20000))]
            edf = self.last_edf
            clouds = _clouds(self.latest_frames.values())
            messages = tuple(self._messages)
            if consume_messages:
                self._messages.clear()
            return Snapshot(
                seq=self._seq, wall_time=time.time(), state=self.state, run_state=self.run_state,
                status=self.status_line(), boxes=self.world.boxes() if self.world else (), plan=self.plan,
                base_path=None if self.sequencer.path is None else self.sequencer.path.copy(),
                object_map=object_map, map_points=points, edf_slice=_edf_slice(edf), clouds=clouds,
                progress=tuple(self.sequencer.progress), active_index=self.sequencer.index,
                sequence_version=self.sequence_version, min_distance_m=self.min_distance_m,
                collisions=len(self.world.collisions) if self.world else 0, timings_ms=dict(self.timings_ms),
                map_kind=self.config.map_kind, constraint=self.config.constraint, speed=self.config.speed,
                messages=messages)

    def publish(self) -> Snapshot:
        """Send a snapshot, with the messages queued since the last publish, to every subscriber."""
        snap = self.snapshot(consume_messages=True)
        for callback in list(self._subscribers):
            try:
                callback(snap)
            except Exception:
                log.exception("snapshot subscriber failed")
        return snap

    def status_line(self) -> str:
        head = {RunState.ESTOP: "EMERGENCY STOP", RunState.PAUSED: "paused", RunState.IDLE: "idle"}.get(self.run_state)
        line = self.sequencer.status_line()
        plan = self.plan
        if plan is not None and plan.status.value not in ("ok", "ok_with_slack"):
            line += f" · controller: {plan.status.value} {plan.message}"
        return f"{head} · {line}" if head else line

    # --- run control (UI, bridge, CLI) -------------------------------------------------------------

    def start(self) -> None:
        """Run the authored sequence from its first subtask (or resume when paused)."""
        with self._lock:
            if self.run_state == RunState.PAUSED:
                self.run_state = RunState.RUNNING
                return
            if self.run_state == RunState.RUNNING:
                return
            self.sequencer = Sequencer(self.robot, self.sequence.model_copy(deep=True), self.config.sequencer,
                                       self.controller.params.N, self.controller.params.dt_s)
            self.controller.reset()
            self.plan = None
            self.run_state = RunState.RUNNING
            log.info("sequence %r started (%d subtasks)", self.sequence.name, len(self.sequence.subtasks))

    def pause(self) -> None:
        """Freeze the simulation and the controller (live mode); `start` resumes, `step` advances."""
        with self._lock:
            if self.run_state in (RunState.RUNNING, RunState.IDLE):
                self.run_state = RunState.PAUSED

    def step(self, seconds: float | None = None) -> None:
        """While paused, advance the simulation by one control period (or `seconds`)."""
        with self._lock:
            if self.run_state != RunState.PAUSED:
                self.notify("step works while paused")
                return
            self._step_budget_s += seconds or 1.0 / self.controller.params.control_rate_hz

    def stop(self) -> None:
        """Stop the sequence; the robot comes to rest."""
        self._halt(RunState.IDLE)

    def emergency_stop(self) -> None:
        """Zero velocity at once; nothing moves until `start` or `reset`."""
        self._halt(RunState.ESTOP)
        self.notify("emergency stop")

    def _halt(self, run_state: RunState) -> None:
        """Enter `run_state`, drop the plan and any delayed ones, command zero velocity now."""
        with self._lock:
            self.run_state = run_state
            self.plan = None
            self._pending_plans.clear()
            self.backend.command(np.zeros(9), self.time)

    def reset(self, scene: Scene | None = None) -> None:
        """Reload the scene (robot back at its start), clear the map, the plan and the progress."""
        with self._lock:
            if scene is not None:
                self._scene = scene
            if self.world is not None:
                self.world.load_scene(self._scene)
                self.world.collisions.clear()
            self.backend.command(np.zeros(9), self.time)
            self.backend.observe()  # drop frames of the old scene
            self.run_state = RunState.IDLE
            self._frames.clear()
            self._pending_plans.clear()
            self.log = RunLog()
            with self._map_lock:
                self._build_parts()

    def set_speed(self, speed: float) -> None:
        """Live mode: sim seconds per wall second (simulation only: a real robot runs in real time)."""
        if self.world is None:
            raise RuntimeError("speed applies to the simulation; a real robot runs in real time")
        self.config = replace(self.config, speed=float(speed))

    def configure(self, map_kind: str | None = None, constraint: str | None = None) -> None:
        """Switch map kind or constraint kind; takes effect now (the map restarts empty)."""
        with self._lock:
            self.config = replace(self.config, map_kind=map_kind or self.config.map_kind,
                                  constraint=constraint or self.config.constraint)
            with self._map_lock:
                if map_kind:
                    self._match_sensing()
                    self.map = make_map(self.config.map_kind, self.robot, self.world, self.config.mapping)
                if constraint:
                    self.controller = make_controller(self.robot, replace(self.config.htmpc, constraint=constraint))

    # --- authoring -------------------------------------------------------------------------------

    def set_sequence(self, sequence: TaskSequence) -> None:
        """Replace the authored sequence; a running sequence keeps its copy until the next start."""
        with self._lock:
            self.sequence = sequence
            self.sequence_version += 1
            if self.run_state != RunState.RUNNING:
                self.sequencer = Sequencer(self.robot, sequence.model_copy(deep=True), self.config.sequencer,
                                           self.controller.params.N, self.controller.params.dt_s)

    # --- scene edits (simulation only) -------------------------------------------------------------

    def _require_world(self) -> SimWorld:
        if self.world is None:
            raise RuntimeError("scene edits need the embedded simulation (this runtime drives a real robot)")
        return self.world

    def add_box(self, box: Box) -> None:
        self._require_world().add_box(box)

    def move_box(self, box_id: str, position: tuple[float, float, float], yaw: float | None = None) -> Box:
        return self._require_world().move_box(box_id, position, yaw)

    def remove_box(self, box_id: str) -> Box:
        return self._require_world().remove_box(box_id)

    def scene(self) -> Scene:
        return self._require_world().scene()

    def randomise_scene(self, seed: int, n_boxes: int = 8) -> Scene:
        """The paper's random scene; the robot is moved to its start."""
        scene = random_scene(seed, n_boxes)
        self.reset(scene)
        return scene

    # --- one control period ----------------------------------------------------------------------

    def _integrate_frames(self, now: float) -> None:
        """Give the map every queued frame older than the modelled perception delay."""
        due = []
        while self._frames and self._frames[0].t <= now - self.config.perception_delay_s + 1e-9:
            due.append(self._frames.popleft())
        if not due:
            return
        for frame in due:
            self.latest_frames[frame.camera] = frame
        from core.types import Observation

        t0 = time.perf_counter()
        with self._map_lock:
            self.map.integrate(Observation(state=self.state, frames=tuple(due), odometry=None))
        self.timings_ms["mapping"] = (time.perf_counter() - t0) * 1e3

    def _control(self, state: RobotState) -> None:
        """Sequencer → references → HTMPC; the plan becomes active after the actuation delay."""
        t0 = time.perf_counter()
        with self._lock:
            if self.run_state != RunState.RUNNING:
                return
            with self._map_lock:
                occupied = self.map.occupied_points()
                t_edf = time.perf_counter()
                edf = self.map.local_edf(state.q[:2])
                self.timings_ms["edf"] = (time.perf_counter() - t_edf) * 1e3
            refs = self.sequencer.update(state, occupied, state.t)
            self.last_edf = edf
            if refs is None:
                self.run_state = RunState.FAILED if self.sequencer.failed else RunState.FINISHED
                self.plan = None
                self._pending_plans.clear()
                if self.sequencer.failed:
                    self.notify(self.sequencer.status_line())
                return
            t_solve = time.perf_counter()
            plan = self.controller.solve(state, refs, edf)
            self.timings_ms["solve"] = (time.perf_counter() - t_solve) * 1e3
            self._pending_plans.append((state.t + self.config.actuation_delay_s, plan))
            self.last_control_wall = time.time()
        self.timings_ms["control"] = (time.perf_counter() - t0) * 1e3

    def _command(self, t: float) -> np.ndarray:
        """The velocity command at sim time t from the active plan (zero when none)."""
        with self._lock:
            while self._pending_plans and self._pending_plans[0][0] <= t + 1e-9:
                self.plan = self._pending_plans.popleft()[1]
            # paused, only the simulation freezes; a real robot would keep moving, so it gets zero
            moving = self.run_state == RunState.RUNNING or (self.run_state == RunState.PAUSED and self.world)
            qdot = self.plan.velocity_at(t) if (moving and self.plan is not None) else np.zeros(9)
        if not np.all(np.isfinite(qdot)):
            self.notify("non-finite command from the plan: stopping")
            qdot = np.zeros(9)
        qdot = self.robot.limits.clip_velocity(qdot)
        self.backend.command(qdot, t)
        return qdot

    def _observe(self) -> RobotState:
        obs = self.backend.observe()
        self.state = obs.state
        if obs.frames:
            with self._frames_ready:
                self._frames.extend(obs.frames)
                self._frames_ready.notify()
        return obs.state

    def _measure(self, qdot: np.ndarray) -> None:
        if self.world is not None:
            self.min_distance_m, _ = self.world.robot_box_distance()
        self.log.record(self.state, self.plan, self.min_distance_m, len(self.world.collisions) if self.world else 0,
                        self.run_state, self.sequencer.index, qdot, dict(self.timings_ms))

    # --- lockstep --------------------------------------------------------------------------------

    def run_lockstep(self, max_duration_s: float, until_done: bool = True, publish_every: int = 0,
                     on_control: Callable[[Runtime], None] | None = None) -> RunLog:
        """Run in simulated time until the sequence ends (or `max_duration_s`); returns the run log.

        Requires the embedded simulation. `publish_every` > 0 publishes a snapshot every that many
        control periods; `on_control` is called after each control step (experiments edit the scene there).
        """
        if not isinstance(self.backend, SimRobot):
            raise RuntimeError("lockstep needs the embedded simulation")
        p = self.controller.params
        dt_cmd = 1.0 / p.command_rate_hz
        per_control = max(1, int(round(p.command_rate_hz / p.control_rate_hz)))
        if self.run_state not in (RunState.RUNNING,):
            self.start()
        self.controller.enforce_timeout = False  # simulated time waits for the solver
        t_end = self.time + max_duration_s
        k = 0
        while self.time < t_end - 1e-9:
            state = self._observe()
            self._integrate_frames(state.t)
            if k % per_control == 0:
                self._control(state)
                if on_control is not None:
                    on_control(self)
                if publish_every and (k // per_control) % publish_every == 0:
                    self.publish()
            qdot = self._command(state.t)
            if k % per_control == 0:
                self._measure(qdot)
            self.backend.step(dt_cmd)
            k += 1
            if until_done and self.run_state in (RunState.FINISHED, RunState.FAILED, RunState.ESTOP):
                break
        self.state = self.backend.observe().state
        return self.log

    # --- live ------------------------------------------------------------------------------------

    def start_live(self) -> None:
        """Start the live threads (physics for the simulation, I/O, mapping, control, publishing)."""
        self._stop_threads.clear()
        self.controller.enforce_timeout = True
        loops = [(self._io_loop, "io"), (self._map_loop, "mapping"), (self._control_loop, "control"),
                 (self._publish_loop, "publish")]
        if isinstance(self.backend, SimRobot):
            loops.insert(0, (self._physics_loop, "physics"))
        for target, name in loops:
            thread = threading.Thread(target=self._guard(target), name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def _guard(self, loop: Callable[[], None]) -> Callable[[], None]:
        """A crashing loop stops the robot and says so instead of dying silently."""
        def run() -> None:
            try:
                loop()
            except Exception as err:
                log.exception("%s loop crashed", threading.current_thread().name)
                self.emergency_stop()
                self.notify(f"{threading.current_thread().name} loop crashed: {err}")
        return run

    def shutdown(self) -> None:
        """Stop the live threads and the robot."""
        self._stop_threads.set()
        with self._frames_ready:
            self._frames_ready.notify_all()
        for thread in self._threads:
            thread.join(timeout=3.0)
        self._threads.clear()
        self.backend.command(np.zeros(9), self.time)

    def _physics_loop(self) -> None:
        try:
            self._run_physics()
        finally:  # GL contexts belong to this thread: free the cameras' renderers here
            self.backend.close()

    def _run_physics(self) -> None:
        dt = 0.01
        next_tick = time.perf_counter()
        while not self._stop_threads.is_set():
            with self._lock:
                paused = self.run_state == RunState.PAUSED and self._step_budget_s <= 1e-9
                if self.run_state == RunState.PAUSED and not paused:
                    self._step_budget_s -= dt
            if not paused:
                self.backend.step(dt)
            next_tick += dt / self.config.speed
            delay = next_tick - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            else:
                next_tick = time.perf_counter()  # behind: never catch up in a burst

    def _io_loop(self) -> None:
        period = 1.0 / self.controller.params.command_rate_hz
        while not self._stop_threads.wait(period / (max(self.config.speed, 1.0) if self.world else 1.0)):
            state = self._observe()
            self._last_qdot = self._command(state.t)

    def _map_loop(self) -> None:
        while not self._stop_threads.is_set():
            with self._frames_ready:
                self._frames_ready.wait(timeout=0.2)
                if not self._frames:
                    continue
                # behind? keep only the newest frame of each camera
                newest: dict[str, DepthFrame] = {}
                for f in self._frames:
                    newest[f.camera] = f
                self._frames.clear()
                self._frames.extend(sorted(newest.values(), key=lambda f: f.t))
            self._integrate_frames(self.state.t + self.config.perception_delay_s)

    def _control_loop(self) -> None:
        period = 1.0 / self.controller.params.control_rate_hz
        next_t = self.time
        while not self._stop_threads.is_set():
            if self.time + 1e-9 < next_t:
                time.sleep(0.002)
                continue
            next_t = self.time + period
            self._control(self.state)
            self._measure(getattr(self, "_last_qdot", np.zeros(9)))

    def _publish_loop(self) -> None:
        period = 1.0 / self.config.publish_hz
        while not self._stop_threads.wait(period):
            self.publish()


CLOUD_STRIDE_PX = 8
"""Every 8th pixel in u and v: about 1200 points per 320 × 240 frame, enough to see what a camera sees."""


def _clouds(frames) -> np.ndarray | None:
    from core.mapping import frame_points

    pts = [frame_points(f, stride=CLOUD_STRIDE_PX) for f in frames]
    return np.concatenate(pts) if pts else None


def _edf_slice(edf: LocalEDF | None) -> EDFSlice | None:
    if edf is None:
        return None
    k = int(np.clip(round((EDF_SLICE_Z_M - edf.origin[2]) / edf.voxel), 0, edf.values.shape[2] - 1))
    return EDFSlice(origin=edf.origin[:2].copy(), voxel=edf.voxel, z_m=float(edf.origin[2] + k * edf.voxel),
                    values=edf.values[:, :, k].copy())


def outcome_counts(progress) -> dict[str, int]:
    """How many subtasks ended in each outcome."""
    return {o.value: sum(p.outcome == o for p in progress) for o in Outcome}
