"""`Runtime`: the studio's one entry to the closed loop of the paper (robot backend, map, sequencer, HTMPC),
used by the UI, the bridge's operator API and the CLI. It runs in two modes:

- **lockstep** (`run_lockstep`): simulated time, one thread, deterministic, as fast as the machine
  allows; optional modelled perception and actuation delays. For tests, reports and benchmarks.
- **live** (`start_live`): supervised wall-clock threads (`app/runtime/live_loops.py`): physics (a backend stepped
  in lockstep: the simulation),
  I/O at 100 Hz (observe, command), mapping as frames arrive, control at 10 Hz, publishing at 20 Hz.

Both run the stages of one `ClosedLoop` (`app/runtime/closed_loop.py`, which also writes down the lock order);
snapshots are assembled by `app/runtime/snapshot_builder.py`. A fault anywhere brakes the robot within its limits
and holds the run in `RunState.FAULT` until `reset`, which builds a new closed loop and new live threads.

Rates (paper): physics 500 Hz, depth 10 Hz, HTMPC 10 Hz, velocity commands 100 Hz interpolated from
the latest plan (`Plan.velocity_at`). The runtime is the only owner of these parts; the UI and the
bridge read `Snapshot`s and call the public methods below.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.map_kind import MapKind
from app.object_label import shown_id
from app.object_names import NameInUseError, UnknownObjectError, find_object
from app.runtime.closed_loop import MOVING_STATES, ClosedLoop, untrusted_notice
from app.runtime.config import RuntimeConfig
from app.runtime.live_loops import LiveLoops
from app.runtime.map_process import MapProcess
from app.runtime.native_memory import limit_arenas, release_free_memory
from app.runtime.problems import ProblemLog
from app.runtime.run_log import RunLog
from app.runtime.snapshot import RunState, Snapshot
from app.runtime.snapshot_builder import build_snapshot, status_line
from app.target_check import check_targets
from core.errors import NotSupportedError
from core.mapping.world_map import WorldMap
from core.params import ConstraintKind
from core.robot.model import RobotModel
from core.scene import Box, Scene, load_scene, random_scene
from core.sim.sim_robot import SimRobot
from core.sim.simulated_backend import is_simulated
from core.sim.world import SimWorld
from core.types import NQ, DepthFrame, LocalEDF, Plan, RobotBackend, RobotState, steps_in_lockstep
from tasks.schema import NamedObject, TaskSequence, anchored_on
from tasks.sequence_file import load_sequence
from tasks.sequencer import Sequencer
from tasks.validation import TargetFinding

if TYPE_CHECKING:
    from core.htmpc import HTMPC

__all__ = ["FAULT_BRAKE_LIMIT_S", "Runtime"]

log = logging.getLogger(__name__)

FAULT_BRAKE_LIMIT_S = 5.0
"""Lockstep: sim time a faulted run may take to come to rest before the run ends anyway."""


class Runtime:
    """Owns the robot backend, the world (simulation) and the current `ClosedLoop`; the public API.

    Without `backend`, a MuJoCo simulation of `scene` is built. A `backend` passed in says what it can do
    (`RobotBackend.abilities`): a simulated one (`SimRobot`) brings its own world (scene edits, ground truth);
    one stepped in lockstep runs in lockstep; any other is a real robot on its own clock (live only)."""

    def __init__(self, config: RuntimeConfig | None = None, scene: Scene | None = None,
                 sequence: TaskSequence | None = None, backend: RobotBackend | None = None) -> None:
        config = config or RuntimeConfig()
        self.robot = RobotModel(config.robot)
        self._scene = scene or (load_scene(config.scene) if config.scene else Scene())
        if backend is None:
            self.world: SimWorld | None = SimWorld(self.robot, config.sim, self._scene)
            self.backend: RobotBackend = SimRobot(self.world, seed=config.seed)
        elif is_simulated(backend):  # a simulation built by the caller (its own cameras, seed, scene)
            self.world, self.backend, self.robot = backend.world, backend, backend.world.robot
            self._scene = self.world.scene()
        else:
            self.world, self.backend = None, backend
            if config.map_kind == "ground_truth":
                raise ValueError("the ground-truth map needs the embedded simulation")
        self.sequence = sequence or (load_sequence(config.sequence) if config.sequence else TaskSequence())
        self.sequence_version = 0
        self._publish_lock = threading.Lock()
        """Guards subscribers, queued messages and the snapshot counter (a leaf lock, see closed_loop)."""
        self._subscribers: list[Callable[[Snapshot], None]] = []
        self._messages: deque[str] = deque(maxlen=20)
        self._seq = 0
        self._live: LiveLoops | None = None
        self._loop = ClosedLoop(self.robot, self.backend, self.world, config, self.sequence, self.notify)

    # --- the current closed loop and what it holds --------------------------------------------------

    @property
    def closed_loop(self) -> ClosedLoop:
        return self._loop

    @property
    def live(self) -> LiveLoops | None:
        """The live threads (None before `start_live` and after `shutdown`)."""
        return self._live

    @property
    def config(self) -> RuntimeConfig:
        return self._loop.config

    @property
    def map(self) -> WorldMap:
        return self._loop.map

    @property
    def controller(self) -> HTMPC:
        return self._loop.controller

    @property
    def sequencer(self) -> Sequencer:
        return self._loop.sequencer

    @property
    def plan(self) -> Plan | None:
        return self._loop.plan

    @property
    def state(self) -> RobotState:
        return self._loop.state

    @property
    def problems(self) -> ProblemLog:
        """Problems of the current run (QP failures, fallbacks, slow solves, faults, stale state, watchdog)."""
        return self._loop.problems

    @property
    def time(self) -> float:
        return self._loop.state.t

    @property
    def log(self) -> RunLog:
        return self._loop.log

    @property
    def run_state(self) -> RunState:
        return self._loop.run_state

    @property
    def under_way(self) -> bool:
        """A run is under way (running, or paused/stopped mid-sequence): sequence edits wait for the next run."""
        return self._loop.under_way

    @property
    def fault(self) -> str | None:
        """Why the run is faulted (None when it is not); Start is refused until `reset`."""
        return self._loop.fault_reason

    @property
    def last_edf(self) -> LocalEDF | None:
        return self._loop.last_edf

    @property
    def latest_frames(self) -> dict[str, DepthFrame]:
        return self._loop.latest_frames

    @property
    def last_control_wall(self) -> float:
        return self._loop.last_control_wall

    @property
    def timings_ms(self) -> dict[str, float]:
        return self._loop.timings_ms

    @property
    def min_distance_m(self) -> float:
        return self._loop.min_distance_m

    def motion_allowed(self) -> bool:
        """Whether a non-zero command may go out now: running, or braking after a fault."""
        return self._loop.run_state in MOVING_STATES

    # --- subscribers ---------------------------------------------------------------------------

    def subscribe(self, callback: Callable[[Snapshot], None]) -> Callable[[], None]:
        """Call `callback(snapshot)` on every publish; returns a function that unsubscribes."""
        with self._publish_lock:
            self._subscribers.append(callback)
        return lambda: self._unsubscribe(callback)

    def _unsubscribe(self, callback: Callable[[Snapshot], None]) -> None:
        with self._publish_lock:
            if callback in self._subscribers:
                self._subscribers.remove(callback)

    def notify(self, message: str) -> None:
        """Queue an operator-facing message (error or warning) for the next snapshot."""
        log.warning(message)
        with self._publish_lock:
            self._messages.append(message)

    def snapshot(self, consume_messages: bool = False) -> Snapshot:
        """The current state of everything, as one value (`publish` hands the queued messages on)."""
        with self._publish_lock:
            self._seq += 1
            seq, messages = self._seq, tuple(self._messages)
            if consume_messages:
                self._messages.clear()
        return build_snapshot(self._loop, seq, messages, self.sequence_version)

    @property
    def snapshots_begun(self) -> int:
        """`seq` of the newest snapshot begun so far (snapshots are numbered as they begin, from 1)."""
        with self._publish_lock:
            return self._seq

    def publish(self) -> Snapshot:
        """Send a snapshot, with the messages queued since the last publish, to every subscriber."""
        snap = self.snapshot(consume_messages=True)
        with self._publish_lock:
            subscribers = list(self._subscribers)
        for callback in subscribers:
            try:
                callback(snap)
            except Exception:
                log.exception("snapshot subscriber failed")
        return snap

    def status_line(self) -> str:
        loop = self._loop
        notice = untrusted_notice(loop.health(loop.state.t), loop.config.htmpc.delta_safe_m)
        return status_line(loop.run_state, loop.view.status, loop.plan, loop.fault_reason, notice)

    # --- run control (UI, bridge, CLI) -------------------------------------------------------------

    def start(self) -> None:
        """Resume the active subtask after a pause, a stale-state pause, a stop or an emergency stop; else run
        the authored sequence from its first subtask (starting over is `reset`'s job).

        Raises `FaultError` (with the reason) while the run is faulted: `reset` first."""
        self._loop.start(self.sequence)

    def pause(self) -> None:
        """Freeze the simulation and the controller (live mode); `start` resumes, `step` advances."""
        self._loop.pause()

    def step(self, seconds: float | None = None) -> None:
        """While paused, advance the simulation by one control period (or `seconds`)."""
        if not self._loop.add_step(seconds):
            self.notify("step works while paused")

    def stop(self) -> None:
        """Stop the sequence; the robot comes to rest (after a fault it goes on braking within its limits);
        `start` resumes the active subtask."""
        self._loop.stop()

    def skip(self) -> None:
        """Skip the active subtask (e.g. one with no path to its goal); the run goes on with the next one."""
        if not self._loop.skip():
            raise ValueError("no active subtask to skip: Start the sequence first")

    def emergency_stop(self) -> None:
        """Zero velocity at once; nothing moves until `start` (resumes the active subtask) or `reset`."""
        self._loop.halt(RunState.ESTOP)
        self.notify("emergency stop")

    def reset(self, scene: Scene | None = None) -> None:
        """Reload the scene (robot back at its start), clear the map, the plan, the progress and a fault;
        a new closed loop, with new live threads if they were running."""
        if scene is not None and self.world is not None:
            self.world.check_scene(scene)  # a box inside the robot is refused before anything stops
        live = self._live is not None
        self._stop_live()
        if scene is not None:
            self._scene = scene
        if self.world is not None:
            self.world.load_scene(self._scene)
            self.world.collisions.clear()
        self.backend.command(np.zeros(NQ), self.time)
        old = self._loop
        map_process = old.release_map()
        old.log.close()
        del old
        release_free_memory()
        self._loop = ClosedLoop(self.robot, self.backend, self.world, self._loop.config, self.sequence,
                                self.notify)
        if live:
            self.start_live(map_process)
        elif map_process is not None:
            map_process.close(keep=False)

    def set_speed(self, speed: float) -> None:
        """Live mode: sim seconds per wall second (a backend stepped in lockstep only: a real robot runs in
        real time)."""
        if not steps_in_lockstep(self.backend):
            raise NotSupportedError("speed applies to the simulation; a real robot runs in real time")
        self._loop.set_speed(speed)

    def configure(self, map_kind: MapKind | None = None, constraint: ConstraintKind | None = None) -> None:
        """Switch map kind or constraint kind; takes effect now (the map restarts empty)."""
        self._loop.configure(map_kind, constraint)

    # --- authoring -------------------------------------------------------------------------------

    def set_sequence(self, sequence: TaskSequence, *, scene_may_change: bool = False, indices: list[int] | None = None,
                     source: str = "sequence", text: str | None = None) -> list[TargetFinding]:
        """Replace the authored sequence once its targets pass the target checks (`app.target_check`, as at
        every other edge; `indices`: only those subtasks); a run under way (running, or paused or stopped
        mid-sequence, which Start resumes) keeps its copy to its end: the edit runs in the next run. Raises
        `TargetError` (nothing changes); returns the warnings."""
        warnings = check_targets(self, sequence, scene_may_change=scene_may_change, indices=indices, source=source,
                                 text=text)
        self.sequence = sequence
        self.sequence_version += 1
        self._loop.set_sequence(sequence)
        return warnings

    def name_object(self, name: str, object_id: str,
                    size: tuple[float, float, float] | None = None) -> TaskSequence:
        """Name a mapped object (`object_<n>`; a scene box id with the ground-truth map) for anchored targets, with
        its full size (m) if known: bound now and saved with the sequence where it is. Naming it again with its own
        name sets its size. `UnknownObjectError` (no such object), `NameTakenError` (the name is bound to another
        object, or the object has another name), ValueError (a bad name or size: NaN, ≤ 0), `TargetError` (an
        anchored target on the name fails its checks where the object is: the name is then not bound)."""
        loop = self.closed_loop
        with loop.using_map() as world_map:
            obj = find_object(world_map, self.world, object_id)
        if obj is None:
            raise UnknownObjectError(f"no object {shown_id(object_id)} in the map")
        seq = self.sequence
        named = NamedObject(position=(float(obj.position[0]), float(obj.position[1]), float(obj.position[2])),
                            yaw_deg=math.degrees(obj.yaw), size=size)
        sequence = TaskSequence.model_validate({**seq.model_dump(),
                                                "objects": {**seq.model_dump()["objects"], name: named.model_dump()}})
        with loop.step_lock:  # the control step reads the names (live mode: another thread)
            loop.names.check_free(name, object_id)
            undo = loop.names.name(name, obj, self.time, size)
            loop.refresh_objects_view()  # the target checks below see the anchors on the name where it is
        try:
            self.set_sequence(sequence)
        except BaseException:  # refused (or interrupted): the name is not left bound without its sequence
            with loop.step_lock:
                undo()
                loop.refresh_objects_view()
            raise
        with loop.step_lock:
            loop.refresh_objects_view()  # the name (and its size) show at once, paused too
        return sequence

    def unname_object(self, name: str) -> TaskSequence:
        """Take a name away (from its object and the sequence). `UnknownObjectError` if no object has it,
        `NameInUseError` while a subtask of the authored or the running sequence is anchored on it."""
        loop = self.closed_loop
        seq = self.sequence
        if name not in seq.objects and name not in loop.names.bound():
            raise UnknownObjectError(f"no object is named {name}")
        users = anchored_on(seq, name) or anchored_on(loop.sequencer.sequence, name)
        if users:
            raise NameInUseError(f"{name} is the anchor of subtask {', '.join(map(str, users))}: remove or re-anchor "
                                 "those first")
        objects = {k: v for k, v in seq.model_dump()["objects"].items() if k != name}
        sequence = TaskSequence.model_validate({**seq.model_dump(), "objects": objects})
        with loop.step_lock:
            loop.names.forget(name)
        self.set_sequence(sequence)
        with loop.step_lock:
            loop.refresh_objects_view()
        return sequence

    # --- scene edits (simulation only) -------------------------------------------------------------

    def require_world(self) -> SimWorld:
        """The simulated world; `NotSupportedError` (a RuntimeError) when this runtime drives a real robot."""
        if self.world is None:
            raise NotSupportedError("scene edits need the embedded simulation (this runtime drives a real robot)")
        return self.world

    def add_box(self, box: Box) -> None:
        self.require_world().add_box(box)

    def move_box(self, box_id: str, position: tuple[float, float, float], yaw: float | None = None) -> Box:
        return self.require_world().move_box(box_id, position, yaw)

    def remove_box(self, box_id: str) -> Box:
        return self.require_world().remove_box(box_id)

    def scene(self) -> Scene:
        return self.require_world().scene()

    def randomise_scene(self, seed: int, n_boxes: int = 8) -> Scene:
        """The paper's random scene; the robot is moved to its start."""
        scene = random_scene(seed, n_boxes)
        self.reset(scene)
        return scene

    # --- lockstep --------------------------------------------------------------------------------

    def run_lockstep(self, max_duration_s: float, until_done: bool = True, publish_every: int = 0,
                     on_control: Callable[[Runtime], None] | None = None) -> RunLog:
        """Run in simulated time until the sequence ends (or `max_duration_s`); returns the run log.

        Requires a backend stepped in lockstep (`BackendAbilities.steps_in_lockstep`: the embedded
        simulation); any other raises RuntimeError. `publish_every` > 0 publishes a snapshot every that many
        control periods; `on_control` is called after each control step (experiments edit the scene there).
        A fault ends the run once the robot has braked to rest (`run_state` FAULT, `fault` the reason);
        a faulted runtime refuses to run (`FaultError`) until `reset`.
        """
        backend = self.backend
        if not steps_in_lockstep(backend):
            raise NotSupportedError(f"lockstep needs the embedded simulation: this backend ({type(backend).__name__}) "
                                    "runs on its own clock and cannot be stepped; run it live (start_live)")
        loop = self._loop
        p = loop.controller.params
        dt_cmd = 1.0 / p.command_rate_hz
        per_control = max(1, int(round(p.command_rate_hz / p.control_rate_hz)))
        if loop.run_state != RunState.RUNNING:
            self.start()
        loop.controller.enforce_timeout = False  # simulated time waits for the solver
        t_end = self.time + max_duration_s
        k, fault_ticks = 0, 0
        next_control_k, control_steps = 0, 0  # the tick the next periodic control step is due at; steps so far

        def after_control() -> None:
            if on_control is not None:
                on_control(self)
            if publish_every and control_steps % publish_every == 0:
                self.publish()

        while self.time < t_end - 1e-9:
            if loop.tick(dt_cmd, k >= next_control_k, after_control):
                next_control_k, control_steps = k + per_control, control_steps + 1  # a triggered step restarts it
            loop.guarded("physics", backend.step, dt_cmd)
            k += 1
            if loop.fault_reason is not None:
                fault_ticks += 1
                if loop.braked() or fault_ticks * dt_cmd > FAULT_BRAKE_LIMIT_S:
                    break
            elif until_done and loop.run_state in (RunState.FINISHED, RunState.FAILED, RunState.ESTOP):
                break
        loop.guarded("observe", loop.observe, dt_cmd)
        return loop.log

    # --- live ------------------------------------------------------------------------------------

    def start_live(self, map_process: MapProcess | None = None) -> None:
        """Start the supervised live threads (physics for the simulation, I/O, mapping, control, publishing);
        the object or voxel map in its own process (`map_process`, when one is handed on by `reset`)."""
        if self._live is not None:
            return
        limit_arenas()  # the live threads are rebuilt on every Reset (app/runtime/native_memory.py)
        self._live = LiveLoops(self._loop, self.publish, self.config.publish_hz)
        self._live.start(map_process)

    def _stop_live(self) -> list[str]:
        """Stop the live threads; the names of those left behind."""
        live, self._live = self._live, None
        if live is None:
            return []
        stuck = live.stop()
        if stuck:
            self.notify(f"loops that did not stop in time (left behind): {', '.join(stuck)}")
        return stuck

    def shutdown(self) -> None:
        """Stop the live threads and the robot; an isolated map comes back into this process; the cameras'
        renderers, which every live start reuses, are freed (unless a physics thread left behind may render)."""
        stuck = self._stop_live()
        self._loop.restore_map()
        self.backend.command(np.zeros(NQ), self.time)
        if steps_in_lockstep(self.backend) and "physics" not in stuck:
            self.backend.close()
