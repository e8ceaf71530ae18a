"""Who may watch the live Foxglove server: the studio's rule, for a protocol without a login of its own.

The SDK's WebSocket server checks nobody. On this machine (the default 127.0.0.1) it is served as it is.
Bound to any other address, or for a real robot (`--backend bridge`), the SDK server listens on 127.0.0.1
only and `TokenGate` listens on the asked address: a WebSocket handshake is relayed only when its URL
carries the access token (`ws://HOST:PORT/?token=...`, new every start; Foxglove's "Open connection"
takes the whole URL), compared in constant time; any other request gets 401 and nothing else.
"""

from __future__ import annotations

import asyncio
import http
import secrets
import threading
from urllib.parse import parse_qs, urlsplit

from websockets.asyncio.client import connect
from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from app.foxglove_live import FoxgloveLive
from app.runtime.snapshot import Snapshot
from app.ui.access import is_loopback
from core.robot.model import RobotModel

SUBPROTOCOL = "foxglove.sdk.v1"
"""The Foxglove WebSocket subprotocol the SDK 0.30 server speaks."""


class TokenGate:
    """A WebSocket relay on `host:port` to `upstream` (ws://127.0.0.1:...) for clients that bring `token`."""

    def __init__(self, host: str, port: int, upstream: str, token: str) -> None:
        self.upstream, self.token = upstream, token
        self._loop = asyncio.new_event_loop()
        self._server: Server | None = None
        started = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(host, port, started), name="foxglove-gate",
                                        daemon=True)
        self._thread.start()
        started.wait(timeout=10.0)
        if self._server is None:
            raise OSError(f"could not serve the Foxglove gate on {host}:{port}")
        self.port = int(self._server.sockets[0].getsockname()[1]) if port == 0 else port

    def _run(self, host: str, port: int, started: threading.Event) -> None:
        asyncio.set_event_loop(self._loop)

        async def start() -> None:
            self._server = await serve(self._relay, host, port, process_request=self.check,
                                       subprotocols=[SUBPROTOCOL], max_size=None)  # type: ignore[list-item]

        try:
            self._loop.run_until_complete(start())
        finally:
            started.set()
        self._loop.run_forever()

    def check(self, connection: ServerConnection, request: Request) -> Response | None:
        """None relays the handshake; a Response (401) refuses it."""
        token = parse_qs(urlsplit(request.path).query).get("token", [""])[0]
        if token and secrets.compare_digest(token.encode(), self.token.encode()):
            return None
        body = b"this Foxglove server needs its access link: the ws://HOST:PORT/?token=... URL printed at start\n"
        headers = Headers({"Content-Type": "text/plain; charset=utf-8", "Content-Length": str(len(body))})
        return Response(http.HTTPStatus.UNAUTHORIZED.value, "Unauthorized", headers, body)

    async def _relay(self, client: ServerConnection) -> None:
        async with connect(self.upstream, subprotocols=[SUBPROTOCOL], max_size=None) as upstream:  # type: ignore[list-item]
            async def pump(source, sink) -> None:
                try:
                    async for message in source:
                        await sink.send(message)
                except ConnectionClosed:
                    pass

            tasks = [asyncio.ensure_future(pump(client, upstream)), asyncio.ensure_future(pump(upstream, client))]
            _, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            for task in pending:
                task.cancel()

    def close(self) -> None:
        async def stop() -> None:
            if self._server is not None:
                self._server.close()
                await self._server.wait_closed()

        asyncio.run_coroutine_threadsafe(stop(), self._loop).result(timeout=10.0)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5.0)


class GatedFoxglove:
    """A `FoxgloveLive` on 127.0.0.1 behind a `TokenGate` on the asked address (same subscriber interface)."""

    def __init__(self, host: str, port: int, robot: RobotModel | None = None) -> None:
        self.live = FoxgloveLive("127.0.0.1", 0, robot=robot)
        self.gate = TokenGate(host, port, self.live.url, secrets.token_urlsafe(24))
        self.host = host

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.gate.port}/?token={self.gate.token}"

    def __call__(self, snap: Snapshot) -> None:
        self.live(snap)

    def close(self) -> None:
        self.gate.close()
        self.live.close()


def serve_foxglove(host: str, port: int, require_token: bool = False,
                   robot: RobotModel | None = None) -> FoxgloveLive | GatedFoxglove:
    """The live server on `host:port`: open on loopback, behind the token gate elsewhere or when asked."""
    if is_loopback(host) and not require_token:
        return FoxgloveLive(host, port, robot=robot)
    return GatedFoxglove(host, port, robot=robot)
