"""`LocalizationWorker`: live, the localizer's registrations on a thread of their own (issue 28).

A registration (`Localizer.correct`: thinning, GICP, the gates) takes tens of milliseconds; run in the mapping
stage, as lockstep does, it would hold up the next integration, and run in the control step it would delay the
plan. Live, the mapping stage hands the frames the localizer wants (`ClosedLoop.localize`) to this worker and
goes on; the worker registers the newest of them (an older one still waiting is dropped, counted in `dropped`:
the localizer asks for one frame every 1 / `rate_hz` anyway), and the correction becomes due at the frame's stamp
plus the modelled processing time. The I/O loop applies it at its next observation (`Localizer.apply_due`, cheap):
neither the control step nor the mapping stage ever waits for a registration.

The worker is also the health check's timer: every iteration, a registration or not (it waits at most
`HEALTH_PERIOD_S` for a frame), it watches the pose's health (`ClosedLoop.after_registrations`), so a run whose
frames and control steps have stopped (a camera gone, the run idle) still finds the pose untrusted after
`untrusted_after_s` and says so.

small_gicp holds the GIL while it aligns (measured: a 45 ms registration kept a thread sleeping 1 ms waiting up
to 77 ms), so the other threads of the process are not free of it: `bench/localization_live.py` measures what
it costs the control and I/O loops, with localization on and off.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any, Protocol

import numpy as np

from app.thread_priority import lower_thread_niceness
from core.types import DepthFrame


class RegisteringLoop(Protocol):
    """What the worker needs of the closed loop (`ClosedLoop`; a protocol, so that the two modules do not import each
    other)."""

    fault_reason: str | None

    @property
    def localizing(self) -> bool: ...

    def register(self, frame: DepthFrame, base: np.ndarray) -> Any: ...

    def after_registrations(self) -> None: ...

HEALTH_PERIOD_S = 0.25
"""Longest wait for a frame (wall s): the pose's health is watched at least this often."""


class LocalizationWorker:
    """The registrations of one `ClosedLoop`, live: frames in (`submit`, from the mapping stage), one registration
    per `tick` (the supervised "localization" loop of `app/runtime/live_loops.py`), the health watched every tick."""

    def __init__(self, loop: RegisteringLoop, health_period_s: float = HEALTH_PERIOD_S) -> None:
        self.loop = loop
        self.health_period_s = health_period_s
        self._wanted: deque[tuple[DepthFrame, np.ndarray]] = deque()
        self._ready = threading.Condition()
        self.registrations = 0
        """Registrations run so far."""
        self.dropped = 0
        """Frames handed over and dropped for a newer one before their registration began."""
        self.health_checks = 0
        """Ticks that watched the pose's health (every tick, with or without a registration)."""
        self.wall_ms: deque[float] = deque(maxlen=10_000)
        """Wall time of each recent registration (ms): the reference's preparation and the registration together."""
        self.threads: set[str] = set()
        """Names of the threads that ran a registration (the worker's own only: what the tests check)."""
        self.niceness: int | None = None
        """The niceness the worker's thread lowers itself to at its first tick (None: its creator's)."""
        self._reniced = False

    def submit(self, wanted: list[tuple[DepthFrame, np.ndarray]]) -> None:
        """Frames to register, each with the base pose at its exposure; only the newest waits (never blocks)."""
        if not wanted:
            return
        with self._ready:
            self._wanted.extend(wanted)
            while len(self._wanted) > 1:
                self._wanted.popleft()
                self.dropped += 1
            self._ready.notify()

    def wake(self) -> None:
        """End a wait for frames now (stopping)."""
        with self._ready:
            self._ready.notify_all()

    def tick(self) -> None:
        """Wait up to `health_period_s` for a frame; register it if one came; watch the pose's health."""
        if not self._reniced:
            self._reniced = True
            if self.niceness is not None:
                lower_thread_niceness(self.niceness)
        with self._ready:
            if not self._wanted:
                self._ready.wait(self.health_period_s)
            job = self._wanted.popleft() if self._wanted else None
        if job is not None and self.loop.fault_reason is None:
            t0 = time.perf_counter()
            correction = self.loop.register(*job)
            if correction is not None:
                self.wall_ms.append((time.perf_counter() - t0) * 1e3)
                self.registrations += 1
                self.threads.add(threading.current_thread().name)
        if self.loop.localizing:
            self.loop.after_registrations()
            self.health_checks += 1
