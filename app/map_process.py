"""`MapProcess`: an object or voxel map run in its own process, behind the `WorldMap` interface.

Why: mapping is the heaviest CPU work of a live run (numpy, scipy, open3d), and much of it holds the GIL.
In the runtime's process it starved the threads that must keep time, the I/O loop and the bridge's event
loop: late commands and spurious stale-state pauses (figures in bench/closed_loop.py). In a process of
its own it competes only for a core.

The worker starts empty (imports take seconds on a loaded machine); until it says it is ready, the map
works here as before. Then the map object itself moves to the worker (pickled) and comes back on
`close()`. Every call is a request answered in order: `integrate` waits for the worker (the caller's
thread sleeps on the pipe, holding no GIL) and brings back the new snapshot and occupied points, so
`snapshot()` and `occupied_points()` are answered here; `local_edf` asks the worker. A worker that dies,
raises or does not answer within `timeout_s` makes the call raise `MapProcessError`, which the closed loop
turns into a fault. Callers serialise calls (the closed loop's map lock); `abort()` may come from any
thread and ends a call that waits.
"""

from __future__ import annotations

import logging
import multiprocessing
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from core.mapping.world_map import WorldMap
from core.types import LocalEDF, ObjectMapSnapshot, Observation

log = logging.getLogger(__name__)

TIMEOUT_S = 10.0
"""Longest a request may take (an integration on a loaded machine takes well under a second)."""


class MapProcessError(RuntimeError):
    """The mapping process failed, died or did not answer."""


def _serve(conn: Connection) -> None:
    """The worker: import the maps, say 'ready', then answer requests until 'close' (handing the map back)
    or the pipe closes."""
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
                value = (world_map.snapshot(), world_map.occupied_points(), dict(world_map.timings_ms))
            elif op == "local_edf":
                value = world_map.local_edf(arg)
            elif op == "close":
                conn.send(("ok", world_map))
                return
            else:
                raise ValueError(f"unknown request {op!r}")
            conn.send(("ok", value))
        except Exception as err:  # reported to the caller, which faults the run
            conn.send(("error", f"{type(err).__name__}: {err}"))


class MapProcess:
    """`world_map` running in a worker process (once the worker is ready); the same interface."""

    def __init__(self, world_map: WorldMap, timeout_s: float = TIMEOUT_S) -> None:
        self.timeout_s = timeout_s
        self._local: WorldMap | None = world_map
        """The map while it works here (until the worker is ready), None once the worker has it."""
        self._ready = False
        self._snapshot: ObjectMapSnapshot | None = None
        self._occupied = np.zeros((0, 3))
        self.timings_ms: dict[str, float] = dict(world_map.timings_ms)
        ctx = multiprocessing.get_context("spawn")  # never fork a process that runs threads
        self._conn, child = ctx.Pipe()
        self._process = ctx.Process(target=_serve, args=(child,), name="mapping", daemon=True)
        self._process.start()
        child.close()

    @property
    def pid(self) -> int | None:
        return self._process.pid

    @property
    def isolated(self) -> bool:
        """Whether the map has moved to the worker."""
        return self._local is None

    def _call(self, op: str, arg: Any = None) -> Any:
        try:
            self._conn.send((op, arg))
            if not self._conn.poll(self.timeout_s):
                raise MapProcessError(f"the mapping process did not answer {op} within {self.timeout_s:.0f} s")
            kind, value = self._conn.recv()
        except (EOFError, OSError) as err:
            raise MapProcessError(f"the mapping process is gone ({type(err).__name__}: {err})") from err
        if kind == "error":
            raise MapProcessError(f"{op} failed in the mapping process: {value}")
        return value

    def _here(self) -> WorldMap | None:
        """The map if it still works here; hands it to the worker as soon as the worker is ready."""
        if self._local is None:
            return None
        try:
            if not self._ready and self._conn.poll(0):
                self._ready = self._conn.recv()[0] == "ready"
        except (EOFError, OSError) as err:
            raise MapProcessError(f"the mapping process is gone ({type(err).__name__}: {err})") from err
        if not self._ready:
            return self._local
        self._call("adopt", self._local)
        self._snapshot, self._occupied = self._local.snapshot(), self._local.occupied_points()
        self._local = None
        return None

    def integrate(self, obs: Observation) -> None:
        here = self._here()
        if here is not None:
            here.integrate(obs)
            self.timings_ms = dict(here.timings_ms)
        else:
            self._snapshot, self._occupied, self.timings_ms = self._call("integrate", obs)

    def snapshot(self) -> ObjectMapSnapshot:
        return self._local.snapshot() if self._local is not None else self._snapshot

    def occupied_points(self) -> np.ndarray:
        return self._local.occupied_points() if self._local is not None else self._occupied

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        here = self._here()
        if here is not None:
            return here.local_edf(centre_xy)
        return self._call("local_edf", np.asarray(centre_xy, dtype=float))

    def abort(self) -> None:
        """End the worker now, from any thread (a call waiting on it fails at once); its map is lost."""
        if self._process.is_alive():
            self._process.kill()

    def close(self, keep: bool = True) -> WorldMap | None:
        """End the worker; with `keep`, its map (None if the worker cannot hand it back)."""
        world_map = self._local
        if world_map is None and keep and self._process.is_alive():
            try:
                world_map = self._call("close")
            except MapProcessError as err:
                log.warning("the mapping process did not hand its map back: %s", err)
        self.abort()
        self._process.join(timeout=2.0)
        self._conn.close()
        return world_map
