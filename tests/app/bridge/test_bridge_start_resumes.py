"""Start after a stale-state pause resumes the subtask that was active (the bridge pauses the run when the
driver's state goes stale; the operator's Start goes on where it stood). The other interruptions (pause, stop,
emergency stop): tests/app/test_start_resumes.py."""

from __future__ import annotations

import httpx
import pytest
from websockets.sync.client import ClientConnection

from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from tests.app.bridge.conftest import StateStreamer, wait_until

pytestmark = pytest.mark.wallclock


def test_start_after_a_stale_state_pause_resumes_the_active_subtask(api: httpx.Client, bridge: BridgeServer,
                                                                    raw_driver: ClientConnection) -> None:
    runtime = Runtime(RuntimeConfig(map_process=False), backend=bridge.robot)
    bridge.attach(runtime)
    runtime.start_live()
    try:
        with StateStreamer(raw_driver) as streamer:
            assert api.post("/api/run/start").json()["run_state"] == "running"
            assert wait_until(lambda: runtime.sequencer.progress[0].elapsed_s > 0.5, timeout_s=60)
        assert wait_until(lambda: runtime.run_state == RunState.PAUSED, timeout_s=10)  # stale: paused
        sequencer, elapsed = runtime.sequencer, runtime.sequencer.progress[0].elapsed_s
        with StateStreamer(raw_driver, t0=streamer.t + 5.0):  # the driver's clock ran on while it was silent
            assert wait_until(lambda: not bridge.link.is_stale(), timeout_s=10)
            assert api.post("/api/run/start").json()["run_state"] == "running"
            assert wait_until(lambda: runtime.sequencer.progress[0].elapsed_s > elapsed + 0.2, timeout_s=60)
            resumed = runtime.sequencer.progress[0].elapsed_s
        assert runtime.sequencer is sequencer and runtime.sequencer.index == 0
        assert resumed < elapsed + 3.0  # the silent 5 s did not count toward the subtask's timeout
    finally:
        runtime.shutdown()
