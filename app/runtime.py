"""The closed loop: the simulated robot stepped in real time, snapshots published to subscribers.

Live mode runs physics in its own thread at wall-clock pace; subscribers (the UI) receive
snapshots at `publish_hz` from another thread, so a slow browser never slows physics.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.snapshot import Snapshot
from core.params import SimParams
from core.robot.model import RobotModel
from core.sim.scene import Scene, load_scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld

log = logging.getLogger(__name__)

DEFAULT_SCENE = Path(__file__).parents[1] / "core" / "sim" / "scenes" / "default.yaml"


@dataclass(frozen=True)
class RuntimeConfig:
    """How to run: which scene, at which pace."""

    scene: Path = DEFAULT_SCENE
    physics_dt_s: float = 0.01
    """Wall-clock chunk of physics per loop iteration (MuJoCo steps at 500 Hz inside it)."""
    publish_hz: float = 20.0
    speed: float = 1.0


class Runtime:
    """Owns the world, the robot backend and the loop threads; the single source of snapshots."""

    def __init__(self, config: RuntimeConfig | None = None, scene: Scene | None = None) -> None:
        self.config = config or RuntimeConfig()
        self.robot = RobotModel()
        self.world = SimWorld(self.robot, SimParams(), scene or load_scene(self.config.scene))
        self.backend = SimRobot(self.world)
        self._subscribers: list[Callable[[Snapshot], None]] = []
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._seq = 0
        self.running = True

    def subscribe(self, callback: Callable[[Snapshot], None]) -> Callable[[], None]:
        """Call `callback(snapshot)` on every publish; returns a function that unsubscribes."""
        self._subscribers.append(callback)
        return lambda: self._subscribers.remove(callback)

    def snapshot(self) -> Snapshot:
        """The current state of everything, as one value."""
        self._seq += 1
        return Snapshot(seq=self._seq, wall_time=time.time(), state=self.world.state(), boxes=self.world.boxes(),
                        running=self.running)

    def start(self) -> None:
        """Start the physics and publishing threads (live mode)."""
        self._stop.clear()
        for target, name in ((self._physics_loop, "physics"), (self._publish_loop, "publish")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        """Stop the threads and the robot."""
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._threads.clear()
        self.backend.stop()

    def _physics_loop(self) -> None:
        dt = self.config.physics_dt_s
        next_tick = time.perf_counter()
        while not self._stop.is_set():
            if self.running:
                self.backend.step(dt)
            next_tick += dt / self.config.speed
            delay = next_tick - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            else:
                next_tick = time.perf_counter()  # behind: do not try to catch up in a burst

    def _publish_loop(self) -> None:
        period = 1.0 / self.config.publish_hz
        while not self._stop.wait(period):
            snap = self.snapshot()
            for callback in list(self._subscribers):
                try:
                    callback(snap)
                except Exception:
                    log.exception("snapshot subscriber failed")
