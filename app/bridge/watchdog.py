"""The stale-state watchdog: when the driver's state gets older than `stale_after_s` (150 ms), or the
driver disconnects, command zero velocity at once and tell the server (which pauses the runtime).

It checks every `period_s` (5 ms) in its own thread, so it acts even when the runtime sends no
commands. While the state stays stale, `BridgeRobot` turns every runtime command into zero velocity;
when fresh state comes back nothing resumes by itself: the operator starts the run again.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from app.bridge.robot_link import RobotLink

log = logging.getLogger(__name__)


class StaleStateWatchdog:
    """Watches the link's state age; on going stale: zero command, then `on_stale(age_s)`."""

    def __init__(self, link: RobotLink, on_stale: Callable[[float], None] | None = None,
                 period_s: float = 0.005) -> None:
        self.link = link
        self.on_stale = on_stale
        self.period_s = period_s
        self.stale = True
        self._gone_told = True
        """Whether `on_stale` heard of the driver's disconnection since state was last fresh."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start checking in a daemon thread."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="bridge-watchdog", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            try:
                self.check()
            except Exception:
                log.exception("watchdog check failed")

    def check(self) -> None:
        """One check: act on a fresh → stale or stale → fresh transition."""
        age = self.link.state_age_s()
        stale = age > self.link.stale_after_s
        gone = age == float("inf")
        if stale and not self.stale:
            self.stale, self._gone_told = True, gone
            self.link.send_zero("stale_state")
            self.link.record("stale", f"state {age * 1e3:.0f} ms old" if not gone else "driver gone")
            self.link.count("stale_events")
            if self.on_stale is not None:
                self.on_stale(age)
        elif stale and gone and not self._gone_told:  # stale first (a loaded machine), then the link closed
            self._gone_told = True
            self.link.record("stale", "driver gone")
            if self.on_stale is not None:
                self.on_stale(age)
        elif not stale and self.stale:
            self.stale, self._gone_told = False, False
            self.link.record("fresh", "state is fresh again")
