"""Replay a recorded run in the studio: the same views, with run controls driving playback.

`ReplaySource` offers the part of the `Runtime` interface the studio uses; edits that only make sense
on a live robot (scene, sequence, map kind) are refused with a clear message.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from app.recording import read_recording
from app.snapshot import Snapshot
from core.robot.model import RobotModel
from tasks.schema import TaskSequence


@dataclass(frozen=True)
class _ReplayConfig:
    speed: float = 1.0
    map_kind: str = "replay"
    constraint: str = "replay"


class ReplaySource:
    """Plays snapshots of a recording at their recorded sim-time pace (× speed)."""

    def __init__(self, path: Path) -> None:
        self.recording = read_recording(path)
        self.snapshots: list[Snapshot] = list(self.recording)
        if not self.snapshots:
            raise ValueError(f"{path} holds no snapshots")
        self.robot = RobotModel()
        self.config = _ReplayConfig(map_kind=self.snapshots[0].map_kind, constraint=self.snapshots[0].constraint)
        self.sequence = TaskSequence(name=f"replay of {Path(path).name}")
        self.sequence_version = 0
        self.index = 0
        self.playing = False
        self._subscribers: list[Callable[[Snapshot], None]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="replay", daemon=True)

    @property
    def state(self):
        return self.snapshots[self.index].state

    def snapshot(self) -> Snapshot:
        return replace(self.snapshots[self.index], status=f"replay {self.index + 1}/{len(self.snapshots)} · "
                                                          f"{self.snapshots[self.index].status}", messages=())

    def subscribe(self, callback: Callable[[Snapshot], None]) -> Callable[[], None]:
        self._subscribers.append(callback)
        return lambda: self._subscribers.remove(callback) if callback in self._subscribers else None

    def _publish(self) -> None:
        snap = self.snapshot()
        for callback in list(self._subscribers):
            callback(snap)

    def start_live(self) -> None:
        self._thread.start()

    def shutdown(self) -> None:
        self._stop.set()

    def _loop(self) -> None:
        while not self._stop.is_set():
            if not self.playing or self.index >= len(self.snapshots) - 1:
                self.playing = False
                self._stop.wait(0.05)
                continue
            dt = self.snapshots[self.index + 1].state.t - self.snapshots[self.index].state.t
            self._stop.wait(max(0.0, dt) / self.config.speed)
            self.index += 1
            self._publish()

    # run controls drive playback
    def start(self) -> None:
        self.playing = True

    def pause(self) -> None:
        self.playing = False

    def step(self, seconds: float | None = None) -> None:
        self.playing = False
        self.index = min(self.index + 1, len(self.snapshots) - 1)
        self._publish()

    def stop(self) -> None:
        self.playing = False

    def reset(self, scene=None) -> None:
        self.playing = False
        self.index = 0
        self._publish()

    def emergency_stop(self) -> None:
        self.playing = False

    def set_speed(self, speed: float) -> None:
        self.config = replace(self.config, speed=float(speed))

    def _refuse(self, *_, **__) -> None:
        raise RuntimeError("this is a replay: scene, sequence and map edits need a live run")

    configure = set_sequence = add_box = move_box = remove_box = randomise_scene = scene = _refuse


def wait_until_played(source: ReplaySource, timeout_s: float) -> bool:
    """Block until playback reaches the end (for tests); True if it did."""
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        if source.index >= len(source.snapshots) - 1:
            return True
        time.sleep(0.02)
    return False
