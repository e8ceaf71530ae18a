"""The reference driver in its own process: it streams state and depth frames, follows commands, stops
the robot when commands stop, and exits when the bridge goes away."""

from __future__ import annotations

import numpy as np
import pytest

from app.bridge.server import BridgeServer
from tests.app.bridge.conftest import FORWARD, Commander, wait_until

pytestmark = [pytest.mark.slow, pytest.mark.wallclock]


def test_driver_streams_state_and_frames_of_both_cameras(bridge: BridgeServer, start_driver) -> None:
    start_driver()
    frames = []
    assert wait_until(lambda: frames.extend(bridge.robot.observe().frames) or
                      {f.camera for f in frames} >= {"hand", "base"}, timeout_s=20)
    for frame in frames:
        assert frame.depth.shape == (240, 320) and np.all(np.isfinite(frame.depth))
        assert np.count_nonzero(frame.depth) > 0 and frame.depth.max() <= frame.range_m
        assert np.allclose(frame.T_world_camera[3], [0, 0, 0, 1]) and frame.K[2, 2] == 1.0
    assert bridge.link.rejected == {}


def test_driver_follows_velocity_commands(bridge: BridgeServer, start_driver) -> None:
    start_driver()
    x0 = bridge.robot.observe().state.q[0]
    commander = Commander(bridge.robot, FORWARD)
    try:
        assert wait_until(lambda: bridge.robot.observe().state.q[0] > x0 + 0.2, timeout_s=20)
    finally:
        commander.stop()
    assert bridge.link.counts["acks"] > 0
    # On a loaded runner a state can arrive later than stale_after_s; the bridge then sends zero with
    # reason `stale_state`, which is the watchdog doing its job, not a failure to follow commands.
    reasons = [c.reason for c in commander.sent[5:-5]]
    assert set(reasons) <= {"runtime", "stale_state"}, set(reasons)
    assert reasons.count("runtime") >= 0.8 * len(reasons), reasons.count("stale_state")


def test_driver_stops_the_robot_when_commands_stop(bridge: BridgeServer, moving_robot) -> None:
    driver, commander = moving_robot
    commander.stop()
    assert wait_until(lambda: abs(bridge.robot.observe().state.v[0]) < 1e-3, timeout_s=10)
    assert wait_until(lambda: "stopped the robot" in driver.output, timeout_s=5)
    assert driver.proc.poll() is None, "commands stopping is no reason to exit"


def test_driver_exits_when_the_bridge_goes_away(bridge: BridgeServer, moving_robot) -> None:
    driver, commander = moving_robot
    commander.stop()
    bridge.stop()
    assert driver.proc.wait(timeout=20) == 3
    assert wait_until(lambda: "link lost, robot stopped" in driver.output, timeout_s=5)
