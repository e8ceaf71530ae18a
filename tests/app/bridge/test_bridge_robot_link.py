"""The robot link over a real socket: what a driver sends reaches `BridgeRobot`; commands and acks go
round; malformed text and binary messages are answered with an error, counted, and never passed on."""

from __future__ import annotations

import json

import httpx
import numpy as np
import pytest
from websockets.sync.client import ClientConnection, connect

from app.bridge.depth_framing import encode_depth_frame
from app.bridge.server import BridgeServer
from core.types import DepthFrame
from tests.app.bridge.conftest import ZERO_STATE, StateStreamer, auth, send_state, wait_until

pytestmark = pytest.mark.wallclock


def _frame(t: float, depth: np.ndarray | None = None) -> DepthFrame:
    depth = np.full((12, 16), 1.5, dtype=np.float32) if depth is None else depth
    K = np.array([[20.0, 0.0, 7.5], [0.0, 20.0, 5.5], [0.0, 0.0, 1.0]])
    return DepthFrame(t=t, camera="hand", depth=depth, K=K, T_world_camera=np.eye(4))


def _health(bridge: BridgeServer) -> dict:
    return httpx.get(f"{bridge.url}/api/health").json()


def _next(ws: ClientConnection, kind: str) -> dict:
    while True:
        msg = json.loads(ws.recv(timeout=5))
        if msg["type"] == kind:
            return msg


def test_state_and_frames_reach_the_robot_backend(bridge: BridgeServer, raw_driver: ClientConnection) -> None:
    q = [0.5, -0.25, 0.1, 0.0, -1.6, 2.2, -0.2, 1.57, 3.14]
    send_state(raw_driver, 2.0, q=q, odometry={"pose": [0.49, -0.25, 0.1], "twist": [0.0, 0.0, 0.0]})
    raw_driver.send(encode_depth_frame(_frame(2.0)))
    assert wait_until(lambda: bridge.link.counts["frames"] == 1)
    obs = bridge.robot.observe()
    assert obs.state.t == 2.0 and np.allclose(obs.state.q, q)
    assert np.allclose(obs.odometry.pose, [0.49, -0.25, 0.1])
    assert len(obs.frames) == 1 and obs.frames[0].camera == "hand" and np.all(obs.frames[0].depth == 1.5)
    assert bridge.robot.observe().frames == ()
    health = _health(bridge)
    assert health["driver_connected"] and health["driver"].startswith("127.0.0.1:")
    assert health["counters"]["states"] == 1 and health["counters"]["frames"] == 1


def test_commands_carry_seq_and_acks_measure_the_round_trip(bridge: BridgeServer,
                                                            raw_driver: ClientConnection) -> None:
    qdot = np.linspace(-0.1, 0.1, 9)
    with StateStreamer(raw_driver):
        assert wait_until(lambda: bridge.link.state is not None)
        bridge.robot.command(qdot, 1.0)
        command = _next(raw_driver, "command")
        raw_driver.send(json.dumps({"type": "ack", "seq": command["seq"], "t": 1.01}))
        assert wait_until(lambda: _health(bridge)["counters"]["acks"] == 1)
    assert command["reason"] == "runtime" and command["t"] == 1.0 and np.allclose(command["qdot"], qdot)
    assert _health(bridge)["command_rtt_median_ms"] > 0.0


def test_a_command_that_is_not_finite_goes_out_as_zero(bridge: BridgeServer, raw_driver: ClientConnection) -> None:
    send_state(raw_driver, 1.0)
    assert wait_until(lambda: bridge.link.state is not None)
    bridge.robot.command(np.full(9, np.nan), 1.0)
    command = _next(raw_driver, "command")
    assert command["reason"] == "invalid_command" and command["qdot"] == [0.0] * 9
    assert bridge.robot.rejected_commands == 1


MALFORMED_TEXT = [
    ("not json at all", "bad_json", "Invalid JSON"),
    ('{"type": "state", "t": 1.0, "q": [0,0,0,0,0,0,0,0,NaN], "v": [0,0,0,0,0,0,0,0,0]}', "invalid_state",
     "state.q.8: Input should be a finite number"),
    ('{"type": "state", "t": 1.0, "q": [0,0,0,0,0,0,0,0], "v": [0,0,0,0,0,0,0,0,0]}', "invalid_state",
     "state.q: List should have at least 9 items"),
    ('{"type": "state", "t": Infinity, "q": [0,0,0,0,0,0,0,0,0], "v": [0,0,0,0,0,0,0,0,0]}', "invalid_state",
     "state.t"),
    ('{"type": "state", "t": 1.0, "q": [0,0,0,0,0,0,0,0,0], "v": [0,0,0,0,0,0,0,0,0], "x": 1}', "invalid_state",
     "state.x: Extra inputs are not permitted"),
    ('{"type": "state", "t": "1.0", "q": [0,0,0,0,0,0,0,0,0], "v": [0,0,0,0,0,0,0,0,0]}', "invalid_state",
     "state.t: Input should be a valid number"),
    ('{"type": "state", "t": 1.0, "q": [0,0,0,0,0,0,0,0,0], "v": [0,0,0,0,0,0,0,0,0], "pose_source": "slam"}',
     "invalid_state", "state.pose_source: Input should be 'odometry' or 'localized'"),
    ('{"type": "teleport"}', "invalid_message", "does not match any of the expected tags"),
    ("[1, 2, 3]", "invalid_message", "object"),
    ('{"type": "ack", "seq": 99999, "t": 0.0}', "stale_ack", "not awaiting an ack"),
]


@pytest.mark.parametrize(("text", "code", "says"), MALFORMED_TEXT)
def test_malformed_text_is_rejected_counted_and_not_passed_on(bridge: BridgeServer, raw_driver: ClientConnection,
                                                              text: str, code: str, says: str) -> None:
    raw_driver.send(text)
    error = _next(raw_driver, "error")
    assert error["code"] == code and says in error["message"] and error["count"] == 1
    assert bridge.link.state is None
    assert _health(bridge)["counters"]["rejected"] == {code: 1}


def _truncated(data: bytes) -> bytes:
    return data[:-7]


def _nan_depth(t: float) -> bytes:
    depth = np.full((12, 16), 1.0, dtype=np.float32)
    depth[0, 0] = np.nan
    return encode_depth_frame(_frame(t, depth))


MALFORMED_FRAMES = [
    (lambda: _truncated(encode_depth_frame(_frame(1.0))), "needs exactly"),
    (lambda: encode_depth_frame(_frame(1.0))[:6], "truncated frame"),
    (lambda: b"\x00" * 64, "bad magic"),
    (lambda: _nan_depth(1.0), "NaN or infinite"),
]


@pytest.mark.parametrize(("make", "says"), MALFORMED_FRAMES)
def test_malformed_frames_are_rejected_counted_and_not_passed_on(bridge: BridgeServer, raw_driver: ClientConnection,
                                                                 make, says: str) -> None:
    raw_driver.send(make())
    error = _next(raw_driver, "error")
    assert error["code"] == "invalid_frame" and says in error["message"]
    assert bridge.robot.observe().frames == ()
    assert _health(bridge)["counters"]["rejected"] == {"invalid_frame": 1}
    assert _health(bridge)["counters"]["frames"] == 0


def test_time_going_backwards_is_rejected(bridge: BridgeServer, raw_driver: ClientConnection) -> None:
    send_state(raw_driver, 5.0)
    send_state(raw_driver, 4.0, q=[1.0] * 9)
    error = _next(raw_driver, "error")
    assert error["code"] == "invalid_state" and "backwards" in error["message"]
    assert bridge.robot.observe().state.t == 5.0 and np.all(bridge.robot.observe().state.q == 0.0)


def test_the_link_survives_rejections(bridge: BridgeServer, raw_driver: ClientConnection) -> None:
    for _ in range(50):
        raw_driver.send("{oops")
        raw_driver.send(b"\x01\x02")
    errors = [_next(raw_driver, "error") for _ in range(100)]
    assert {e["code"] for e in errors} == {"bad_json", "invalid_frame"} and errors[-1]["count"] == 50
    send_state(raw_driver, 1.0, **{**ZERO_STATE, "q": [0.1] * 9})
    assert wait_until(lambda: bridge.link.state is not None)
    rejected = _health(bridge)["counters"]["rejected"]
    assert rejected == {"bad_json": 50, "invalid_frame": 50}
    assert np.allclose(bridge.robot.observe().state.q, 0.1)


def test_a_driver_reconnecting_with_its_clock_restarted_keeps_robot_time_increasing(
        bridge: BridgeServer, raw_driver: ClientConnection) -> None:
    send_state(raw_driver, 7.0)
    assert wait_until(lambda: bridge.link.state is not None)
    raw_driver.close()
    assert wait_until(lambda: not bridge.link.connected)
    with connect(bridge.robot_url, additional_headers=auth(bridge.token)) as again:
        _next(again, "welcome")
        send_state(again, 0.5)
        send_state(again, 0.6)
        assert wait_until(lambda: bridge.link.counts["states"] == 3)
        assert bridge.robot.observe().state.t == pytest.approx(7.1)
        bridge.robot.command(np.zeros(9), 7.1)
        assert _next(again, "command")["t"] == pytest.approx(0.6)
