"""`RuntimeAttachment`: the runtime the operator API controls, and the latest snapshot it published.

The bridge reads the runtime the way the UI does, through published `Snapshot`s. In live mode the
runtime publishes at 20 Hz; when no snapshot newer than `max_age_s` is at hand (lockstep, or right
after a run-control request) the attachment asks the runtime to publish one, which every subscriber
receives (so no operator message is taken from the UI).

Snapshots can arrive out of order: the publish thread may have assembled one before a run-control request
and hand it over after it (and the attachment's own publish may overtake the thread's). So the cache only
takes a snapshot newer (by `seq`) than the one it holds and than every snapshot begun before the latest
`invalidate`: a Start that answered "running" is never followed by a view from before it.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

from app.runtime.snapshot import RunState, Snapshot
from core.types import steps_in_lockstep

if TYPE_CHECKING:
    from app.runtime import Runtime


class RuntimeAttachment:
    """A runtime plus a cache of its latest published snapshot."""

    def __init__(self, runtime: Runtime, max_age_s: float = 0.2) -> None:
        self.runtime = runtime
        self.max_age_s = max_age_s
        self._lock = threading.Lock()
        self._latest: Snapshot | None = None
        self._received_at = 0.0
        self._min_seq = 0
        """Snapshots with `seq` up to this were begun before the latest `invalidate` (or are older than the
        cached one): never cached."""
        self._unsubscribe = runtime.subscribe(self._receive)

    def _receive(self, snap: Snapshot) -> None:
        with self._lock:
            if snap.seq <= self._min_seq:
                return
            self._latest, self._received_at, self._min_seq = snap, time.monotonic(), snap.seq

    def snapshot(self) -> Snapshot:
        """The latest snapshot, published anew if the cached one is older than `max_age_s`."""
        with self._lock:
            snap, age = self._latest, time.monotonic() - self._received_at
        if snap is None or age > self.max_age_s:
            snap = self.runtime.publish()
        return snap

    def invalidate(self) -> None:
        """The runtime changed (a run-control request): the next read publishes a new snapshot."""
        begun = self.runtime.snapshots_begun
        with self._lock:
            self._latest, self._min_seq = None, max(self._min_seq, begun)

    @property
    def simulates(self) -> bool:
        """Whether the backend is a simulation the runtime may edit (`BackendAbilities.simulated`: scene edits
        and the ground-truth map need it)."""
        return self.runtime.world is not None  # the runtime holds a world exactly when the backend declares one

    @property
    def steps(self) -> bool:
        """Whether the runtime steps its backend (`BackendAbilities.steps_in_lockstep`: step and speed need it)."""
        return steps_in_lockstep(self.runtime.backend)

    @property
    def running(self) -> bool:
        return self.runtime.run_state == RunState.RUNNING

    def detach(self) -> None:
        self._unsubscribe()
