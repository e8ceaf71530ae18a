"""Stale-state safety: a driver that dies or freezes gets zero velocity within the 200 ms the issue names.

Deadlines are measured on this process's monotonic clock: from the kill (or from the last state the
bridge received) to the zero command the bridge issued. The slack over the stale threshold (150 ms)
covers the watchdog's 5 ms tick and thread scheduling on a loaded 2-core machine.
"""

from __future__ import annotations

import json
import os
import signal
import time

import numpy as np
import pytest
from websockets.sync.client import ClientConnection

from app.bridge.server import BridgeServer
from tests.app.bridge.conftest import send_state, wait_until

pytestmark = pytest.mark.wallclock

DEADLINE_S = 0.2
"""Zero velocity within this of a driver's death (the issue)."""
SCHEDULING_SLACK_S = 0.05


def _zero_after(bridge: BridgeServer, since: float):
    return next((e for e in bridge.link.events if e.kind == "zero_command" and e.at >= since), None)


def test_state_older_than_200_ms_sends_a_zero_command(bridge: BridgeServer, raw_driver: ClientConnection) -> None:
    for k in range(10):
        send_state(raw_driver, k * 0.01)
        time.sleep(0.01)
    assert wait_until(lambda: bridge.link.counts["states"] == 10 and any(e.kind == "fresh" for e in bridge.link.events))
    last_state = bridge.link.state_received_at
    while True:
        msg = json.loads(raw_driver.recv(timeout=2))
        if msg["type"] == "command":
            break
    assert msg["reason"] == "stale_state" and msg["qdot"] == [0.0] * 9
    zero = _zero_after(bridge, last_state)
    stale_s = bridge.link.stale_after_s
    assert stale_s < DEADLINE_S - 0.02  # caught by age alone inside the deadline, one state period spare
    assert stale_s < zero.at - last_state <= stale_s + SCHEDULING_SLACK_S, zero.at - last_state
    assert bridge.robot.send(np.ones(9), 0.1).reason == "stale_state"


@pytest.mark.slow
def test_killed_driver_gets_zero_within_200_ms(bridge: BridgeServer, moving_robot) -> None:
    driver, commander = moving_robot
    killed_at = time.monotonic()
    os.kill(driver.proc.pid, signal.SIGKILL)
    assert wait_until(lambda: _zero_after(bridge, killed_at) is not None, timeout_s=2)
    zero = _zero_after(bridge, killed_at)
    assert wait_until(lambda: sum(c.at > zero.at for c in commander.sent) >= 5, timeout_s=2)
    assert zero.at - killed_at <= DEADLINE_S, f"zero command {zero.at - killed_at:.3f} s after the kill"
    after = [c for c in commander.sent if c.at > zero.at]
    assert all(c.reason == "stale_state" and not np.any(c.qdot) for c in after)


@pytest.mark.slow
def test_frozen_driver_gets_zero_then_moves_on_when_it_thaws(bridge: BridgeServer, moving_robot) -> None:
    driver, _ = moving_robot
    driver.signal(signal.SIGSTOP)
    frozen_at = time.monotonic()
    assert wait_until(lambda: _zero_after(bridge, frozen_at) is not None, timeout_s=2)
    zero = _zero_after(bridge, frozen_at)
    last_state = bridge.link.state_received_at
    stale_s = bridge.link.stale_after_s
    assert stale_s < zero.at - last_state <= stale_s + SCHEDULING_SLACK_S, zero.at - last_state
    assert bridge.link.last_command.reason == "stale_state" and bridge.link.last_command.delivered
    driver.signal(signal.SIGCONT)
    assert wait_until(lambda: not bridge.watchdog.stale, timeout_s=10)
    assert wait_until(lambda: bridge.robot.observe().state.v[0] > 0.25, timeout_s=10)
    assert [e.kind for e in bridge.link.events if e.at >= frozen_at][:3] == ["zero_command", "stale", "fresh"]


def test_a_disconnection_after_a_stale_pause_is_still_reported() -> None:
    """On a loaded machine state can go stale before the closed link is noticed: the watchdog tells of
    both, so the operator learns that the driver is gone, not only that its state was late."""
    from app.bridge.watchdog import StaleStateWatchdog

    class Link:
        stale_after_s = 0.15
        age = 0.0

        def state_age_s(self) -> float:
            return self.age

        def send_zero(self, reason: str) -> None: ...
        def record(self, kind: str, detail: str = "") -> None: ...
        def count(self, name: str) -> None: ...

    link, heard = Link(), []
    watchdog = StaleStateWatchdog(link, on_stale=heard.append)
    watchdog.check()  # fresh
    link.age = 0.151
    watchdog.check()
    watchdog.check()
    link.age = float("inf")
    watchdog.check()
    watchdog.check()
    assert heard == [0.151, float("inf")]
