"""A fault as the operator API shows it: `/api/state` carries the fault, Start is refused with the reason
until Reset; with a robot behind the bridge the fault's braking commands go out (not vetoed to zero)."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from app.bridge.server import BridgeServer
from app.runtime.snapshot import RunState
from tests.app.bridge.conftest import wait_until
from tests.app.faults import RaiseOnCall

pytestmark = pytest.mark.wallclock


def test_a_fault_shows_in_the_api_and_blocks_start_until_reset(api: httpx.Client, sim_runtime) -> None:
    sim_runtime.start_live()
    assert api.post("/api/run/start").json()["run_state"] == "running"
    loop = sim_runtime.closed_loop
    loop.map = RaiseOnCall(loop.map, "local_edf", ValueError("edf broke"))
    assert wait_until(lambda: api.get("/api/state").json()["run_state"] == "fault", timeout_s=20)
    state = api.get("/api/state").json()
    assert state["fault"] == "control loop: ValueError: edf broke" and "FAULT" in state["status"]
    refused = api.post("/api/run/start")
    detail = refused.json()["detail"]
    assert refused.status_code == 409 and "edf broke" in detail and "Reset" in detail
    reset = api.post("/api/run/reset").json()
    assert reset["run_state"] == "idle" and reset["fault"] is None
    assert api.post("/api/run/start").json()["run_state"] == "running"
    assert api.get("/api/state").json()["fault"] is None


@pytest.mark.slow
def test_a_fault_brakes_a_bridged_robot_within_its_limits(bridge: BridgeServer, bridge_runtime, start_driver,
                                                          monkeypatch) -> None:
    sent = []  # (command, whether the run was faulted when it went out)
    send = bridge.link.send_command

    def record(qdot, t, reason="runtime"):
        sent.append((send(qdot, t, reason), bridge_runtime.fault is not None))
        return sent[-1][0]

    monkeypatch.setattr(bridge.link, "send_command", record)
    start_driver()
    bridge_runtime.start_live()
    bridge_runtime.start()

    def moving() -> bool:
        if bridge_runtime.run_state == RunState.PAUSED:  # a state gone stale under load paused it: Start resumes
            bridge_runtime.start()
        return bridge.robot.observe().state.v[0] > 0.3

    assert wait_until(moving, timeout_s=60), bridge_runtime.status_line()
    loop = bridge_runtime.closed_loop
    loop.controller = RaiseOnCall(loop.controller, "solve", RuntimeError("solver broke"))
    assert wait_until(lambda: bridge_runtime.fault is not None, timeout_s=10)
    assert wait_until(loop.braked, timeout_s=10)
    first = next(i for i, (_, faulted) in enumerate(sent) if faulted)
    # from the last command before the fault on; zeros the bridge itself sent (state stale under load) aside
    braking = [c for c, _ in sent[first - 1:] if c.reason == "runtime"]
    assert sum(np.any(c.qdot) for c in braking) > 10, "the braking commands were vetoed"
    t = np.array([c.t for c in braking])
    qdot = np.array([c.qdot for c in braking])
    moved = np.diff(t) > 1e-9
    accel = np.abs(np.diff(qdot, axis=0))[moved] / np.diff(t)[moved, None]
    assert np.all(accel <= bridge_runtime.robot.limits.a_max * (1 + 1e-6) + 1e-6)
    assert wait_until(lambda: np.abs(bridge.robot.observe().state.v).max() < 0.05, timeout_s=10)
