"""The `/robot` WebSocket: one robot driver streams state and depth frames in and receives commands.

Without `Authorization: Bearer <token>` the handshake is answered with HTTP 401 (a second driver
while one is connected: 409). Every message is validated before anything reaches the link; a rejected
one is counted and answered with an `error` message naming the field, and nothing of it is passed on.
Messages to the driver go through an `Outbox`: velocity commands latest-wins (a command not yet sent
when a newer one arrives is dropped, never queued behind it), everything else in order.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Mapping
from typing import Any

from fastapi import APIRouter, WebSocket, status
from fastapi.responses import JSONResponse
from pydantic import ValidationError

from app.bridge.auth import Token
from app.bridge.depth_framing import FrameFormatError, decode_depth_frame
from app.bridge.protocol import (
    DRIVER_TEXT,
    Ack,
    ErrorMessage,
    ErrorOut,
    Hello,
    RejectionCode,
    StateMessage,
    Welcome,
    validation_text,
)
from app.bridge.robot_link import LinkBusyError, MessageRejectedError, RobotLink

log = logging.getLogger(__name__)

router = APIRouter()
MAX_TEXT_CHARS = 65536


class Outbox:
    """Messages to one driver, posted from any thread and sent in order by one task."""

    def __init__(self, loop: asyncio.AbstractEventLoop, link: RobotLink) -> None:
        self._loop, self._link = loop, link
        self._command: tuple[int, str] | None = None
        self._others: deque[str] = deque()
        self._ready = asyncio.Event()

    def post_command(self, text: str, seq: int) -> None:
        """From any thread: send this command next, replacing one not sent yet."""
        with contextlib.suppress(RuntimeError):  # a closed loop: the server is stopping, and the link with it
            self._loop.call_soon_threadsafe(self._put_command, text, seq)

    def _put_command(self, text: str, seq: int) -> None:
        if self._command is not None:
            self._link.superseded(self._command[0])
        self._command = (seq, text)
        self._ready.set()

    def post(self, text: str) -> None:
        """From the event loop: send this message (welcome, error) in order."""
        self._others.append(text)
        self._ready.set()

    async def pump(self, websocket: WebSocket) -> None:
        """Send whatever is posted until cancelled."""
        while True:
            await self._ready.wait()
            self._ready.clear()
            while self._others:
                await websocket.send_text(self._others.popleft())
            if self._command is not None:
                text, self._command = self._command[1], None
                await websocket.send_text(text)


def _accept_text(link: RobotLink, text: str, first: bool) -> None:
    if len(text) > MAX_TEXT_CHARS:
        raise MessageRejectedError("invalid_message",
                                   f"text message of {len(text)} characters; at most {MAX_TEXT_CHARS}")
    try:
        msg = DRIVER_TEXT.validate_json(text, strict=True)
    except ValidationError as err:
        kinds = {e["type"] for e in err.errors()}
        heads = {e["loc"][0] for e in err.errors() if e["loc"]}
        code: RejectionCode = ("bad_json" if "json_invalid" in kinds else "invalid_state" if "state" in heads
                               else "invalid_message")
        raise MessageRejectedError(code, validation_text(err)) from err
    if isinstance(msg, StateMessage):
        link.accept_state(msg)
    elif isinstance(msg, Ack):
        link.accept_ack(msg)
    elif isinstance(msg, Hello):
        if not first:  # a driver is named once: a hello mid-stream would rename it in the log and /api/health
            raise MessageRejectedError("invalid_message", f"hello must be the first message of a connection; the "
                                                          f"driver stays {link.driver!r}")
        link.name_driver(msg.driver)


def handle(link: RobotLink, message: Mapping[str, Any], first: bool = False) -> str | None:
    """Pass one received message on to the link (`first`: the connection's first message, where a `hello`
    belongs); returns the error message text if it was rejected."""
    try:
        if message.get("bytes") is not None:
            link.accept_frame(decode_depth_frame(message["bytes"]))
        elif message.get("text") is not None:
            _accept_text(link, message["text"], first)
        return None
    except FrameFormatError as err:
        code: RejectionCode = "invalid_frame"
        text = str(err)
    except MessageRejectedError as err:
        code, text = err.code, str(err)
    count = link.reject(code, text)
    return ErrorMessage(code=code, message=text, count=count).model_dump_json()


async def _deny(websocket: WebSocket, status_code: int, detail: str) -> None:
    """Refuse the handshake with an HTTP status (or, if the server cannot, close with 1008)."""
    headers = {"WWW-Authenticate": "Bearer"} if status_code == status.HTTP_401_UNAUTHORIZED else None
    try:
        await websocket.send_denial_response(JSONResponse(ErrorOut(detail=detail).model_dump(), status_code,
                                                          headers=headers))
    except RuntimeError:
        await websocket.close(code=status.WS_1008_POLICY_VIOLATION, reason=detail)


async def _serve(websocket: WebSocket, link: RobotLink, outbox: Outbox) -> None:
    outbox.post(Welcome(stale_after_s=link.stale_after_s).model_dump_json())
    pump = asyncio.create_task(outbox.pump(websocket))
    first = True
    try:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                break
            error, first = handle(link, message, first), False
            if error is not None:
                outbox.post(error)
    finally:
        pump.cancel()


@router.websocket("/robot")
async def robot_socket(websocket: WebSocket) -> None:
    """The robot link (protocol: docs/bridge.md)."""
    token: Token = websocket.app.state.token
    link: RobotLink = websocket.app.state.link
    if not token.matches_header(websocket.headers.get("authorization")):
        await _deny(websocket, status.HTTP_401_UNAUTHORIZED, "missing or wrong bearer token")
        return
    outbox = Outbox(asyncio.get_running_loop(), link)
    client = f"{websocket.client.host}:{websocket.client.port}" if websocket.client else "driver"
    try:
        link.connect(outbox.post_command, client)
    except LinkBusyError as err:
        await _deny(websocket, status.HTTP_409_CONFLICT, str(err))
        return
    try:
        await websocket.accept()
        await _serve(websocket, link, outbox)
    except Exception as err:  # a broken connection ends this driver's session, never the server
        log.info("robot link closed: %s", err)
    finally:
        link.disconnect()
