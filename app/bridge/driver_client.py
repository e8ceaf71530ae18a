"""`DriverClient`: a Python driver's end of the robot link (the sim driver uses it; so can a real one).

    client = DriverClient("ws://127.0.0.1:8090/robot", name="my-robot")   # token: HTMPC_BRIDGE_TOKEN or the file
    client.connect()                           # → the bridge's Welcome (401 → InvalidStatus)
    client.send_state(t, q, v)                 # 50–100 Hz (pose_source="localized": the robot's own SLAM)
    client.send_frame(depth_frame)             # 5–10 Hz, binary (see depth_framing)
    message = client.receive(timeout_s=0.05)   # Command (acknowledged for you), ErrorMessage or None

Sending and receiving may happen in different threads (the websockets sync client is thread-safe).
A closed link raises `websockets.exceptions.ConnectionClosed`.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
from websockets.sync.client import ClientConnection, connect

from app.bridge.auth import read_token
from app.bridge.depth_framing import encode_depth_frame
from app.bridge.protocol import (
    BRIDGE_TEXT,
    Ack,
    Command,
    DepthEncoding,
    ErrorMessage,
    Hello,
    OdometryIn,
    PoseSourceIn,
    StateMessage,
    Welcome,
)
from core.types import DepthFrame, Odometry

log = logging.getLogger(__name__)


class DriverClient:
    """Connects to the bridge, streams state and frames, receives (and acknowledges) commands."""

    def __init__(self, url: str, token: str | None = None, name: str = "driver", clock=time.monotonic,
                 token_file: Path | None = None) -> None:
        """`token`: the bridge token, else `HTMPC_BRIDGE_TOKEN`, else `token_file` (default: the user's file)."""
        self.url, self.name = url, name
        self._token = token or read_token(token_file)
        self._clock = clock
        self._ws: ClientConnection | None = None
        self.welcome: Welcome | None = None

    def connect(self, open_timeout_s: float = 10.0) -> Welcome:
        """Open the link (bearer token in the handshake), say hello, read the welcome."""
        self._ws = connect(self.url, additional_headers={"Authorization": f"Bearer {self._token}"},
                           open_timeout=open_timeout_s, max_size=2**24, compression=None)
        welcome = BRIDGE_TEXT.validate_json(self._ws.recv(timeout=open_timeout_s))
        if not isinstance(welcome, Welcome):
            raise ConnectionError(f"expected a welcome from the bridge, got {welcome!r}")
        self.welcome = welcome
        self._ws.send(Hello(driver=self.name).model_dump_json())
        return welcome

    @property
    def ws(self) -> ClientConnection:
        if self._ws is None:
            raise ConnectionError("not connected: call connect() first")
        return self._ws

    def send_state(self, t: float, q: np.ndarray, v: np.ndarray, odometry: Odometry | None = None,
                   pose_source: PoseSourceIn = "odometry") -> None:
        """`pose_source`: "odometry" (the runtime localizes it) or "localized" (the robot's own localization)."""
        odo = None if odometry is None else OdometryIn(pose=list(map(float, odometry.pose)),
                                                       twist=list(map(float, odometry.twist)))
        msg = StateMessage(t=t, q=[float(x) for x in q], v=[float(x) for x in v], odometry=odo,
                           pose_source=pose_source)
        self.ws.send(msg.model_dump_json())

    def send_frame(self, frame: DepthFrame, encoding: DepthEncoding = "float32_m") -> None:
        self.ws.send(encode_depth_frame(frame, encoding))

    def receive(self, timeout_s: float | None = None) -> Command | ErrorMessage | None:
        """The next message (None on timeout); commands are acknowledged as soon as they are parsed."""
        try:
            text = self.ws.recv(timeout=timeout_s)
        except TimeoutError:
            return None
        msg = BRIDGE_TEXT.validate_json(text)
        if isinstance(msg, Command):
            self.ws.send(Ack(seq=msg.seq, t=self._clock()).model_dump_json())
        elif isinstance(msg, ErrorMessage):
            log.warning("bridge rejected a message (%s #%d): %s", msg.code, msg.count, msg.message)
        return msg if isinstance(msg, Command | ErrorMessage) else None

    def close(self) -> None:
        if self._ws is not None:
            self._ws.close()
