"""The live threads of a `ClosedLoop`: they only schedule its stages, on wall-clock time.

- physics (a backend stepped in lockstep, `BackendAbilities.steps_in_lockstep`: the simulation): `backend.step`
  of 10 ms of sim time, paced by `speed`, frozen while paused; it first makes the cameras' renderers (the
  first time: a Reset's new thread reuses them), and the other loops start after that (`CAMERA_SETUP_WAIT_S`);
- io: observe + command at the command rate (100 Hz), deadline-paced so the rate holds on average;
- mapping: integrate depth frames as they arrive (only the newest of each camera when behind), the object
  and voxel maps in a process of their own (`app/runtime/map_process.py`: mapping held the GIL these loops need);
- control: one control step (and a run-log row) per control period of robot time, woken by the io loop, and
  (`HTMPCParams.control_on_new_map`) by the mapping loop as soon as the map has taken a new frame;
- localization (with `LocalizationParams.enabled`): the localizer's registrations of the frames the mapping loop
  hands over, off the control and mapping threads (`app/runtime/localization_worker.py`; the io loop applies the
  corrections as they fall due), and the pose's health watched at least every `HEALTH_PERIOD_S`, frames or not;
- publish: a snapshot to the subscribers at `publish_hz`;
- watchdog: every loop must keep beating; a dead or stalled loop is a fault.

The loops, and the other threads of the process (the bridge's event loop), run at the raised priority of
`RuntimeConfig.live_niceness` where the system allows it (`app/thread_priority.py`); the mapping process
`map_process.NICENESS` below them, and so does the localization thread.

Each loop is a `SupervisedLoop`: an exception of any kind in an iteration faults the run (the robot brakes
within its limits, see `ClosedLoop.fault`) and the loop goes on, so no loop is silently dead. After a
fault, `Runtime.reset` stops these threads and starts new ones on a new `ClosedLoop`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from app.runtime.closed_loop import ClosedLoop
from app.runtime.localization_worker import LocalizationWorker
from app.runtime.map_process import NICENESS, MapProcess
from app.runtime.problems import ProblemKind
from app.runtime.snapshot import RunState
from app.thread_priority import boost_threads, set_thread_niceness, thread_niceness
from core.types import steps_in_lockstep

log = logging.getLogger(__name__)

PHYSICS_STEP_S = 0.01
"""Sim time advanced per physics iteration (its wall period is this / speed)."""
MAP_WAIT_S = 0.2
WATCHDOG_PERIOD_S = 0.2
STALL_AFTER_S = {"physics": 5.0, "io": 5.0, "mapping": 15.0, "control": 5.0, "publish": 15.0, "localization": 15.0}
"""A loop that has not finished an iteration for this long (wall s) is stalled: a fault. Generous, so that
a loaded machine does not fault spuriously (the first physics step, which creates the cameras' GL
contexts, took 1.5 s at load 8 on 2 cores); a late control loop is caught sooner by the plan's age
(`MAX_PLAN_AGE_S`), and the backends' own watchdogs stop a robot whose commands stop."""
CAMERA_SETUP_WAIT_S = 10.0
"""Live start: the other loops start once the physics thread has made the cameras' GL contexts (or after
this long, s). Making a context holds the GIL for about 0.3 s: a control step running meanwhile waited it
out and overran its 250 ms budget (measured at the start of live runs, 1 in 3 on a quiet machine)."""
MAX_PLAN_AGE_S = 2.0
"""Live: running on the plan of a control step older than this (robot s) means the control loop is not
keeping up: a fault, so the robot brakes along the plan instead of running to the end of its 3 s horizon."""


@dataclass
class LoopStats:
    """How a loop keeps time: iterations, periods started more than one period late, exceptions."""

    iterations: int = 0
    late: int = 0
    errors: int = 0
    beat: float = field(default_factory=time.monotonic)
    """Monotonic time the latest iteration ended."""
    longest_s: float = 0.0
    """Longest iteration (wall s)."""


class SupervisedLoop:
    """A named daemon thread running `tick()` until stopped, every `period_s()` when given (deadline-paced,
    never catching up in a burst), else back to back (the tick waits on its own). An exception in a tick
    goes to `on_fault` and the loop goes on; anything that ends the thread goes to `on_fault` too."""

    def __init__(self, name: str, tick: Callable[[], object], on_fault: Callable[[str], None],
                 period_s: Callable[[], float] | None = None, niceness: int | None = None) -> None:
        self.name, self.tick, self.on_fault = name, tick, on_fault
        self.niceness = niceness
        """The thread's niceness (`app/thread_priority.py`; None: the creator's)."""
        self.period_s = period_s
        self.stall_after_s = STALL_AFTER_S.get(name, 5.0)
        self.stats = LoopStats()
        self.stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self.stats.beat = time.monotonic()
        self._thread.start()

    def stop(self) -> None:
        self.stopping.set()

    def join(self, timeout_s: float) -> bool:
        """Wait for the thread to end; whether it did."""
        if self._thread.ident is not None:
            self._thread.join(timeout=timeout_s)
        return not self._thread.is_alive()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        set_thread_niceness(self.niceness)
        next_tick = time.perf_counter()
        try:
            while not self.stopping.is_set():
                start = time.monotonic()
                self._iterate()
                self.stats.iterations += 1
                self.stats.beat = time.monotonic()
                self.stats.longest_s = max(self.stats.longest_s, self.stats.beat - start)
                if self.period_s is not None:
                    next_tick = self._pace(next_tick, self.period_s())
        except BaseException as err:  # noqa: BLE001  (SystemExit and the like end the thread: say so)
            self.on_fault(f"{self.name} loop ended: {type(err).__name__}: {err}")

    def _iterate(self) -> None:
        try:
            self.tick()
        except Exception as err:
            if self.stopping.is_set():  # cut short on purpose (a map call aborted at shutdown)
                return
            self.stats.errors += 1
            if self.stats.errors == 1 or self.stats.errors % 1000 == 0:
                log.debug("%s loop: exception #%d", self.name, self.stats.errors, exc_info=True)
            self.on_fault(f"{self.name} loop: {type(err).__name__}: {err}")

    def _pace(self, next_tick: float, period: float) -> float:
        next_tick += period
        delay = next_tick - time.perf_counter()
        if delay > 0:
            self.stopping.wait(delay)
        elif -delay > period:  # more than one period behind: count it, and start afresh from now
            self.stats.late += 1
            next_tick = time.perf_counter()
        return next_tick


class LiveLoops:
    """The supervised threads that run one `ClosedLoop` live, and their watchdog."""

    def __init__(self, loop: ClosedLoop, publish: Callable[[], object], publish_hz: float) -> None:
        self.loop = loop
        self._publish = publish
        self.publish_hz = publish_hz
        p = loop.controller.params
        self.control_period_s = 1.0 / p.control_rate_hz
        self.command_period_s = 1.0 / p.command_rate_hz
        self._control_due = threading.Event()
        self._cameras_ready = threading.Event()
        """Set once the physics thread has made the cameras' renderers (`SteppableBackend.prepare_cameras`)."""
        self._next_control_t = loop.state.t
        self.control_steps = 0
        self.control_lateness_s: deque[float] = deque(maxlen=10000)
        """Robot time each recent control step started after its due time (s)."""
        fault = loop.fault
        self.control = SupervisedLoop("control", self._control_tick, fault)
        self.loops = [SupervisedLoop("io", self._io_tick, fault, self._io_period),
                      SupervisedLoop("mapping", self._map_tick, fault), self.control,
                      SupervisedLoop("publish", self._publish, fault, lambda: 1.0 / self.publish_hz)]
        self.localization: LocalizationWorker | None = None
        """The registrations' worker (with a localizer: `LocalizationParams.enabled` on a perceived map)."""
        if loop.localizer is not None:
            self.localization = LocalizationWorker(loop)
            self.loops.append(SupervisedLoop("localization", self.localization.tick, fault))
        self.physics: SupervisedLoop | None = None
        backend = loop.backend
        if steps_in_lockstep(backend):
            # the cameras' renderers outlive this thread: the next Reset's physics thread renders with them
            # (made anew every Reset, they cost ~0.1 MB of native memory each time: core/sim/gl_release.py)
            self.physics = SupervisedLoop("physics", self._physics_tick, fault, self._physics_period)
            self.loops.insert(0, self.physics)
        self.watchdog = SupervisedLoop("watchdog", self._watch, fault, lambda: WATCHDOG_PERIOD_S)

    def start(self, map_process: MapProcess | None = None) -> None:
        """Start the threads (at raised priority where allowed); the map in its own process (`map_process` if
        one is handed over)."""
        self.loop.controller.enforce_timeout = True
        self.loop.max_plan_age_s = MAX_PLAN_AGE_S + self.loop.config.actuation_delay_s
        niceness = self.loop.config.live_niceness
        boosted = niceness is not None and boost_threads(niceness)
        for loop in [*self.loops, self.watchdog]:
            loop.niceness = niceness if boosted and loop.name != "localization" else None
        if self.localization is not None:  # below the loops that keep time, as the mapping process is
            base = niceness if boosted and niceness is not None else thread_niceness()
            self.localization.niceness = base + NICENESS
        self.loop.localization_worker = self.localization
        if self.loop.config.map_process:
            self.loop.isolate_map(map_process, (niceness if niceness is not None and boosted else thread_niceness())
                                  + NICENESS)
        elif map_process is not None:
            map_process.close(keep=False)
        if self.physics is not None:
            self.physics.start()
            if not self._cameras_ready.wait(CAMERA_SETUP_WAIT_S):
                log.warning("cameras not ready within %.0f s: starting the other loops anyway", CAMERA_SETUP_WAIT_S)
        for loop in [*self.loops, self.watchdog]:
            if loop is not self.physics:
                loop.start()

    def stop(self, timeout_s: float = 3.0) -> list[str]:
        """Stop every thread; the names of those that did not end within `timeout_s` each (a map process a
        stuck thread waits on is ended, so that thread can finish; a thread slow for another reason, such as
        physics making GL contexts on a loaded machine, leaves the worker alone for the next loop)."""
        for loop in [self.watchdog, *self.loops]:
            loop.stop()
        self._control_due.set()
        self.loop.wake_mapping()
        if self.localization is not None:
            self.localization.wake()
        stuck = [loop.name for loop in [self.watchdog, *self.loops] if not loop.join(timeout_s)]
        if stuck and isinstance(self.loop.map, MapProcess) and self.loop.map.calling is not None:
            self.loop.map.abort()
        if stuck:  # a second chance, as long again
            stuck = [loop.name for loop in [self.watchdog, *self.loops] if not loop.join(timeout_s)]
        return stuck

    def stats(self) -> dict[str, LoopStats]:
        return {loop.name: loop.stats for loop in self.loops}

    # --- the ticks -----------------------------------------------------------------------------------

    def _speed(self) -> float:
        """Robot seconds per wall second: the run's speed for a backend the physics loop steps, else 1."""
        return self.loop.config.speed if self.physics is not None else 1.0

    def _physics_period(self) -> float:
        return PHYSICS_STEP_S / self._speed()

    def _io_period(self) -> float:
        return self.command_period_s / max(self._speed(), 1.0)

    def _physics_tick(self) -> None:
        backend = self.loop.backend
        if not steps_in_lockstep(backend):
            return
        if not self._cameras_ready.is_set():
            try:
                backend.prepare_cameras()
            finally:  # a failure faults the run; start() need not wait it out
                self._cameras_ready.set()
                if self.physics is not None:  # the stall clock starts once the cameras exist (seconds under load)
                    self.physics.stats.beat = time.monotonic()
        if self.loop.take_physics_step(PHYSICS_STEP_S):
            backend.step(PHYSICS_STEP_S)
            stamps, world = self.loop.stamps, self.loop.world
            if stamps is not None and world is not None:
                stamps.physics_step(world.time)

    def _io_tick(self) -> None:
        dt_robot = self._io_period() * self._speed()
        state = self.loop.guarded("io loop: observe", self.loop.observe, dt_robot) or self.loop.advance_clock(dt_robot)
        if state.t + 1e-9 >= self._next_control_t or self.loop.control_triggered(state.t):
            self._control_due.set()
        self.loop.command(state.t)

    def _map_tick(self) -> None:
        if self.loop.wait_for_frames(MAP_WAIT_S):
            self.loop.integrate_frames(self.loop.state.t + self.loop.config.perception_delay_s)
            if self.loop.control_triggered(self.loop.state.t):
                self._control_due.set()

    def _control_tick(self) -> None:
        self._control_due.wait(0.05)
        self._control_due.clear()
        state = self.loop.state
        due = self._next_control_t
        if state.t + 1e-9 < due:
            if not self.loop.control_triggered(state.t):
                return
            due = state.t  # a step on the new map, and the period starts from it
        late = state.t - due > self.control_period_s
        self._next_control_t = state.t + self.control_period_s if late else due + self.control_period_s
        self.control_steps += 1
        self.control_lateness_s.append(state.t - due)
        self.control.stats.late += int(late)
        if late and self.loop.run_state == RunState.RUNNING:
            self.loop.problems.record(ProblemKind.WATCHDOG, state.t, f"control step {state.t - due:.2f} s late")
        self.loop.control(state)
        if self.loop.config.actuation_delay_s <= 0.0:  # the new plan's first command now, not at the next I/O tick
            self.loop.command(self.loop.state.t)
        self.loop.measure(self.loop.last_qdot)

    def _watch(self) -> None:
        now = time.monotonic()
        for loop in self.loops:
            if not loop.alive and not loop.stopping.is_set():
                self.loop.fault(f"{loop.name} loop is dead")
            elif now - loop.stats.beat > loop.stall_after_s:
                self.loop.fault(f"{loop.name} loop stalled: no iteration for {now - loop.stats.beat:.1f} s")
