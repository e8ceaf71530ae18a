"""`MapProcess`: an object or voxel map run in its own process, behind the `WorldMap` interface.

Why: mapping is the heaviest CPU work of a live run (numpy, scipy), and much of it holds the GIL.
In the runtime's process it starved the threads that must keep time, the I/O loop and the bridge's event
loop: late commands and spurious stale-state pauses (figures in bench/closed_loop.py). In a process of
its own it competes only for a core.

The worker starts empty (imports take seconds on a loaded machine); until it says it is ready, the map
works here as before. Then the map object itself moves to the worker (pickled) and comes back on
`close()`. `integrate` waits for the worker (the caller's thread sleeps on the pipe, holding no GIL) and
brings back the new snapshot, the occupied points and the local EDF around the robot's position of that
observation; `snapshot()`, `occupied_points()` and `local_edf()` near that position (`RECENTRE_M`) are
answered from those, so the control step never waits for an integration in progress (in this process it
waited on the map's lock). A worker that dies, raises or does not answer within `timeout_s` makes the call
raise `MapProcessError`, which the closed loop turns into a fault. Calls on the pipe are serialised here;
`abort()` may come from any thread and ends a call that waits.

The worker runs at a lower priority than the loops that must keep time (`NICENESS` above theirs): on a
machine short of CPU the map updates less often (only the newest frame of each camera is integrated)
instead of those loops, and the robot's driver, running late. When the loops run at raised priority
(`app/thread_priority.py`), the worker runs at normal priority, beside ordinary programs.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from core.errors import StudioError
from core.mapping.world_map import WorldMap
from core.types import LocalEDF, ObjectMapSnapshot, Observation

log = logging.getLogger(__name__)

TIMEOUT_S = 10.0
"""Longest a request may take (an integration on a loaded machine takes well under a second)."""
RECENTRE_M = 0.5
"""`local_edf` answers with the field of the latest integration when that was centred within this of the
asked centre (an eighth of the 4 m window): control never waits for an integration in progress."""
NICENESS = 5
"""The worker runs at this much lower priority than the live loops: when the machine is short of CPU, the
map (which keeps only the newest frame of each camera) updates less often, rather than the I/O and control loops and the
robot's driver running late. Measured in bench/closed_loop.py."""


class MapProcessError(StudioError, RuntimeError):
    """The mapping process failed, died or did not answer."""


def _serve(conn: Connection, niceness: int) -> None:
    """The worker (at `niceness`, or the nearest it may have): import the maps, say 'ready', then answer
    requests until 'close' (handing the map back) or the pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is the parent's to handle: it asks for the map back
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked since the spawn (`MapProcess`)
    with contextlib.suppress(PermissionError):
        os.setpriority(os.PRIO_PROCESS, 0, max(niceness, -20))
    import core.mapping  # noqa: F401  (the seconds of imports happen before 'ready')

    conn.send(("ready", None))
    world_map: Any = None
    while True:
        try:
            op, arg = conn.recv()
        except (EOFError, OSError):
            return
        try:
            if op == "adopt":
                world_map, value = arg, None
            elif op == "integrate":
                world_map.integrate(arg)
                centre = np.asarray(arg.state.q[:2], dtype=float)
                edf = world_map.local_edf(centre)  # first: the timings handed back then include its own ("edf")
                value = (world_map.snapshot(), world_map.occupied_points(), dict(world_map.timings_ms), edf, centre)
            elif op == "local_edf":
                value = world_map.local_edf(arg)
            elif op == "note_change_evidence":
                note = getattr(world_map, "note_change_evidence", None)  # maps with objects only
                value = None if note is None else note(arg)
            elif op == "close":
                conn.send(("ok", world_map))
                return
            else:
                raise ValueError(f"unknown request {op!r}")
            conn.send(("ok", value))
        except Exception as err:  # reported to the caller, which faults the run
            conn.send(("error", f"{type(err).__name__}: {err}"))


@dataclass(frozen=True)
class _Latest:
    """What the worker handed back after its latest integration."""

    snapshot: ObjectMapSnapshot
    occupied: np.ndarray
    timings_ms: dict[str, float]
    edf: LocalEDF | None = None
    edf_centre: np.ndarray | None = None
    wall: float = field(default_factory=time.perf_counter)
    """When it was handed back (`time.perf_counter`, s): whoever reads it reads it after this."""


class MapProcess:
    """`world_map` running in a worker process (once the worker is ready); the same interface, safe to call
    from several threads (calls on the pipe are serialised here; cached answers need no waiting)."""

    serialises_calls = True
    """The closed loop need not hold its map lock around calls (it would make control wait for mapping)."""

    def __init__(self, world_map: WorldMap, timeout_s: float = TIMEOUT_S, niceness: int | None = None,
                 recentre_m: float = RECENTRE_M) -> None:
        """`niceness`: the worker's (default: `NICENESS` above the calling thread's)."""
        self.timeout_s, self.recentre_m = timeout_s, recentre_m
        self._pipe = threading.RLock()
        self._local: WorldMap | None = world_map
        """The map while it works here (until the worker is ready), None once the worker has it."""
        self._ready = False
        self._closed = False
        self._aborted = False
        """Set by `abort`: the worker is as good as gone even before the kill has taken effect (`alive`)."""
        self._calling: str | None = None
        """The request a thread is waiting on the worker for (None: none)."""
        self._latest: _Latest | None = None
        ctx = multiprocessing.get_context("spawn")  # never fork a process that runs threads
        self._conn, child = ctx.Pipe()
        if niceness is None:
            niceness = os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) + NICENESS
        self._process = ctx.Process(target=_serve, args=(child, min(niceness, 19)), name="mapping", daemon=True)
        # Ctrl+C in a terminal signals the whole process group: the worker is born with SIGINT blocked (a thread's
        # mask is inherited), so even its start-up is not interrupted, and then ignores it.
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            self._process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        child.close()

    @property
    def pid(self) -> int | None:
        return self._process.pid

    @property
    def isolated(self) -> bool:
        """Whether the map has moved to the worker."""
        return self._local is None

    def _call(self, op: str, arg: Any = None) -> Any:
        self._calling = op
        try:
            self._conn.send((op, arg))
            if not self._conn.poll(self.timeout_s):
                raise MapProcessError(f"the mapping process did not answer {op} within {self.timeout_s:.0f} s")
            kind, value = self._conn.recv()
        except (EOFError, OSError) as err:
            raise self._gone(err) from err
        finally:
            self._calling = None
        if kind == "error":
            raise MapProcessError(f"{op} failed in the mapping process: {value}")
        return value

    def _gone(self, err: BaseException) -> MapProcessError:
        """The worker's end of the pipe closed: say how it ended (exit status or signal), as evidence."""
        self._process.join(timeout=0.5)
        code = self._process.exitcode
        how = ("still running" if code is None else f"killed by {signal.Signals(-code).name}" if code < 0
               else f"exit status {code}")
        return MapProcessError(f"the mapping process is gone ({type(err).__name__}: {err}; pid {self._process.pid} "
                               f"{how})")

    def _here(self) -> WorldMap | None:
        """The map if it still works here; hands it to the worker as soon as the worker is ready (under
        the pipe lock)."""
        if self._local is None or self._closed:
            return self._local
        try:
            if not self._ready and self._conn.poll(0):
                self._ready = self._conn.recv()[0] == "ready"
        except (EOFError, OSError) as err:
            raise self._gone(err) from err
        if not self._ready:
            return self._local
        local = self._local
        self._call("adopt", local)
        self._latest = _Latest(local.snapshot(), local.occupied_points(), dict(local.timings_ms))
        self._local = None
        log.info("the map now runs in the mapping process (pid %s)", self._process.pid)
        return None

    @property
    def timings_ms(self) -> dict[str, float]:
        local, latest = self._local, self._latest
        return dict(local.timings_ms) if local is not None else (latest.timings_ms if latest else {})

    @property
    def latest_edf(self) -> tuple[LocalEDF, float] | None:
        """The EDF the worker built after its latest integration and the wall time (`time.perf_counter`) it was
        handed back (None before the first)."""
        latest = self._latest
        return (latest.edf, latest.wall) if latest is not None and latest.edf is not None else None

    def integrate(self, obs: Observation) -> None:
        with self._pipe:
            if self._closed:
                return
            here = self._here()
            if here is not None:
                here.integrate(obs)
                return
            snapshot, occupied, timings, edf, centre = self._call("integrate", obs)
            self._latest = _Latest(snapshot, occupied, timings, edf, centre)

    def note_change_evidence(self, ids: tuple[int, ...]) -> None:
        """Objects localization found off their surfaces (`ObjectMapper.note_change_evidence`), for the map in the
        worker (after an integration in progress; the next integration's snapshot shows it). A map without objects
        ignores them."""
        ids = tuple(int(i) for i in ids)
        with self._pipe:
            if self._closed:
                return
            here = self._here()
            if here is not None:
                note = getattr(here, "note_change_evidence", None)
                if note is not None:
                    note(ids)
                return
            self._call("note_change_evidence", ids)

    def snapshot(self) -> ObjectMapSnapshot:
        with self._pipe if self._local is not None else contextlib.nullcontext():
            local = self._local
            return local.snapshot() if local is not None else self._handed_back().snapshot

    def occupied_points(self) -> np.ndarray:
        with self._pipe if self._local is not None else contextlib.nullcontext():
            local = self._local
            return local.occupied_points() if local is not None else self._handed_back().occupied

    def _handed_back(self) -> _Latest:
        """What the worker last handed back (there is always something once the map is in the worker)."""
        if self._latest is None:
            raise MapProcessError("the mapping process has handed nothing back yet")
        return self._latest

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        """The field of the latest integration when it was centred within `recentre_m` of `centre_xy`
        (no waiting for an integration in progress); else a new one from the worker."""
        centre = np.asarray(centre_xy, dtype=float)[:2]
        latest = self._latest
        if latest is not None and latest.edf is not None and np.hypot(*(centre - latest.edf_centre)) <= self.recentre_m:
            return latest.edf
        with self._pipe:
            if self._closed and latest is not None and latest.edf is not None:
                return latest.edf
            here = self._here()
            if here is not None:
                return here.local_edf(centre)
            return self._call("local_edf", centre)

    @property
    def alive(self) -> bool:
        """Whether the worker can take requests: not closed, not aborted (a killed worker stays 'alive' to
        `is_alive` until the kernel has reaped it: it must never be handed on in that moment), still running."""
        return not self._closed and not self._aborted and self._process.is_alive()

    @property
    def calling(self) -> str | None:
        """The request a thread is waiting on the worker for, if any (what `abort` would cut short)."""
        return self._calling

    def adopt(self, world_map: WorldMap) -> None:
        """Run `world_map` instead (a Reset: a new map, the same worker, no second start-up)."""
        with self._pipe:
            if not self.alive:
                raise MapProcessError("the mapping process is closed or gone")
            if self._local is not None:
                self._local = world_map
                return
            self._call("adopt", world_map)
            self._latest = _Latest(world_map.snapshot(), world_map.occupied_points(), dict(world_map.timings_ms))

    def abort(self) -> None:
        """End the worker now, from any thread (a call waiting on it fails at once); its map is lost."""
        self._aborted = True
        if self._process.is_alive():
            self._process.kill()

    def close(self, keep: bool = True, patience_s: float = TIMEOUT_S) -> WorldMap | None:
        """End the worker after a call in progress (cut short after `patience_s`); with `keep`, its map (None
        if the worker cannot hand it back). Afterwards `integrate` does nothing and queries answer from the
        latest integration."""
        if not self._pipe.acquire(timeout=patience_s):
            self.abort()  # the call waiting on the worker fails at once and lets go of the pipe
            self._pipe.acquire()
        try:
            world_map = self._local
            if world_map is None and keep and not self._closed and self._process.is_alive():
                try:
                    world_map = self._call("close")
                except MapProcessError as err:
                    log.warning("the mapping process did not hand its map back: %s", err)
            self._closed = True
            self.abort()
            self._process.join(timeout=2.0)
            self._conn.close()
        finally:
            self._pipe.release()
        return world_map
