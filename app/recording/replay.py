"""Replay a recorded run in the studio: the same views, a timeline to scrub, play/pause and speed.

`ReplaySource` offers the part of the `Runtime` interface the studio uses; edits that only make sense
on a live robot (scene, sequence, map kind) are refused with a clear message. It reads recordings only
through `app.recording.read_recording` (a sequence of snapshots), whatever the file format.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NoReturn

import numpy as np

from app.recording.recorder import read_recording
from app.runtime.snapshot import Snapshot
from core.errors import NotSupportedError
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import RobotState
from tasks.schema import TaskSequence


@dataclass(frozen=True)
class _ReplayConfig:
    speed: float = 1.0
    map_kind: str = "replay"
    constraint: str = "replay"
    mapping: MappingParams = field(default_factory=MappingParams)
    """A recording does not carry the tunables: the view draws with the defaults."""


def _latest_with(snapshots: list[Snapshot], field: str) -> list[int]:
    """For each index, the latest index at or before it whose snapshot has `field` (-1: none yet). Recordings keep
    heavy fields (map points, depth clouds) only every few snapshots."""
    out, last = [], -1
    for i, snap in enumerate(snapshots):
        if getattr(snap, field) is not None:
            last = i
        out.append(last)
    return out


class ReplaySource:
    """Plays snapshots of a recording at their recorded sim-time pace (× speed); `seek` jumps to a time."""

    def __init__(self, path: Path) -> None:
        self.recording = read_recording(path)
        self.snapshots: list[Snapshot] = list(self.recording)
        if not self.snapshots:
            raise ValueError(f"{path} holds no snapshots")
        self.times = np.array([s.state.t for s in self.snapshots])
        self._points_at = _latest_with(self.snapshots, "map_points")
        self._clouds_at = _latest_with(self.snapshots, "clouds")
        self.robot = RobotModel()
        self.config = _ReplayConfig(map_kind=self.snapshots[0].map_kind, constraint=self.snapshots[0].constraint)
        self.sequence = TaskSequence(name=f"replay of {Path(path).name}")
        self.sequence_version = 0
        self.index = 0
        self.playing = False
        self._lock = threading.RLock()
        self._subscribers: list[Callable[[Snapshot], None]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="replay", daemon=True)

    @property
    def state(self) -> RobotState:
        return self.snapshots[self.index].state

    @property
    def time(self) -> float:
        return float(self.times[self.index])

    @property
    def start_time(self) -> float:
        return float(self.times[0])

    @property
    def end_time(self) -> float:
        return float(self.times[-1])

    def snapshot(self, index: int | None = None) -> Snapshot:
        """The recorded snapshot (at `index`, default the current one) with the map points and depth clouds the
        recording last kept, and a status saying where the replay is."""
        i = self.index if index is None else index
        snap = self.snapshots[i]
        p, c = self._points_at[i], self._clouds_at[i]
        return replace(snap, map_points=None if p < 0 else self.snapshots[p].map_points,
                       clouds=None if c < 0 else self.snapshots[c].clouds, messages=(),
                       status=f"replay {snap.state.t - self.start_time:.1f} / {self.end_time - self.start_time:.1f} s"
                              f" · {snap.status}")

    def history(self, n: int) -> list[Snapshot]:
        """Up to `n` snapshots before the current one (what the plots show up to now)."""
        return self.snapshots[max(0, self.index - n):self.index]

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
            with self._lock:
                at_end = self.index >= len(self.snapshots) - 1
                if at_end:
                    self.playing = False
                playing, i = self.playing, self.index
            if not playing:
                self._stop.wait(0.05)
                continue
            dt = self.times[i + 1] - self.times[i]
            self._stop.wait(max(0.0, dt) / self.config.speed)
            with self._lock:
                if not self.playing or self.index != i:  # paused or scrubbed meanwhile
                    continue
                self.index = i + 1
            self._publish()

    def seek(self, t: float) -> Snapshot:
        """Jump to the last snapshot at or before sim time t (clamped to the recording) and show it."""
        with self._lock:
            self.index = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 1))
        self._publish()
        return self.snapshots[self.index]

    # run controls drive playback
    def start(self) -> None:
        with self._lock:
            if self.index >= len(self.snapshots) - 1:
                self.index = 0  # play again from the start
            self.playing = True

    def pause(self) -> None:
        self.playing = False

    def step(self, seconds: float | None = None) -> None:
        with self._lock:
            self.playing = False
            target = self.time + seconds if seconds else None
        if target is None:
            with self._lock:
                self.index = min(self.index + 1, len(self.snapshots) - 1)
            self._publish()
        else:
            self.seek(target)

    def stop(self) -> None:
        self.playing = False

    def skip(self) -> None:
        raise ValueError("a replay shows the recorded run: nothing to skip")

    def reset(self, scene=None) -> None:
        self.playing = False
        self.seek(self.start_time)

    def emergency_stop(self) -> None:
        self.playing = False

    def set_speed(self, speed: float) -> None:
        if not 0.05 <= float(speed) <= 50.0:
            raise ValueError(f"replay speed must be within 0.05–50, got {speed}")
        self.config = replace(self.config, speed=float(speed))

    def _refuse(self, *_, **__) -> NoReturn:
        raise NotSupportedError("this is a replay: scene, sequence and map edits need a live run")

    configure = set_sequence = add_box = move_box = remove_box = randomise_scene = scene = _refuse


def wait_until_played(source: ReplaySource, timeout_s: float) -> bool:
    """Block until playback reaches the end (for tests); True if it did."""
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        if source.index >= len(source.snapshots) - 1:
            return True
        time.sleep(0.02)
    return False
