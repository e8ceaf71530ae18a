"""The robot link's limits as docs/bridge.md states them, over a real socket: text messages up to 65,536
characters, a message above 16 MiB closes the link with code 1009, a `hello` only as the first message."""

from __future__ import annotations

import json

import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from app.bridge.robot_socket import MAX_TEXT_CHARS
from app.bridge.server import BridgeServer
from tests.app.bridge.conftest import ROOT, ZERO_STATE, auth, send_state, wait_until
from tests.app.bridge.test_bridge_robot_link import _next

pytestmark = pytest.mark.wallclock

FLAT = " ".join((ROOT / "docs" / "bridge.md").read_text().split())
MAX_MESSAGE_BYTES = 16 * 2**20


def _padded_state(t: float, chars: int) -> str:
    """A valid state message padded with JSON whitespace to exactly `chars` characters."""
    text = json.dumps({"type": "state", "t": t, **ZERO_STATE})
    return text[:-1] + " " * (chars - len(text)) + "}"


def test_text_up_to_the_limit_passes_and_one_character_more_is_refused(bridge: BridgeServer,
                                                                       raw_driver: ClientConnection) -> None:
    raw_driver.send(_padded_state(1.0, MAX_TEXT_CHARS))
    assert wait_until(lambda: bridge.link.state is not None and bridge.link.state.t == 1.0, timeout_s=5)
    raw_driver.send(_padded_state(2.0, MAX_TEXT_CHARS + 1))
    error = _next(raw_driver, "error")
    assert error["code"] == "invalid_message" and f"at most {MAX_TEXT_CHARS}" in error["message"]
    state = bridge.link.state
    assert state is not None and state.t == 1.0
    assert f"{MAX_TEXT_CHARS:,} characters" in FLAT


def test_a_message_above_16_mib_closes_the_link_with_1009(bridge: BridgeServer) -> None:
    with connect(bridge.robot_url, additional_headers=auth(bridge.token), compression=None) as ws:
        _next(ws, "welcome")
        with pytest.raises(ConnectionClosed) as closed:  # the close may come while the message is still going out
            ws.send(b"\x00" * (MAX_MESSAGE_BYTES + 1))
            while True:
                ws.recv(timeout=10)
    # the close frame reaches the client unless the transport broke while the message was still going out;
    # the bridge's own log says which code it closed with either way
    assert closed.value.rcvd is None or closed.value.rcvd.code == 1009
    assert wait_until(lambda: not bridge.link.connected, timeout_s=5)  # a new driver may connect
    assert "close code 1009" in FLAT


def test_hello_names_the_driver_only_as_the_first_message(bridge: BridgeServer) -> None:
    with connect(bridge.robot_url, additional_headers=auth(bridge.token), compression=None) as ws:
        ws.send(json.dumps({"type": "hello", "driver": "arm-1"}))
        _next(ws, "welcome")
        send_state(ws, 1.0)
        ws.send(json.dumps({"type": "hello", "driver": "someone-else"}))
        error = _next(ws, "error")
    assert error["code"] == "invalid_message" and "first message" in error["message"]
    assert bridge.link.driver == "arm-1"
