"""`BridgeServer`: the bridge's FastAPI app served by uvicorn in a background thread, plus its watchdog.

    bridge = BridgeServer(port=8090)          # 127.0.0.1 unless host= says otherwise; port=0: any free port
    bridge.start()                            # returns once the socket listens
    runtime = Runtime(config, backend=bridge.robot)
    bridge.attach(runtime)                    # operator API, watchdog pause and motion gate get the runtime
    ...
    bridge.stop()                             # zero command, close the driver's link, stop serving
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import uvicorn

from app.bridge.attachment import RuntimeAttachment
from app.bridge.auth import resolve_token
from app.bridge.bridge_robot import BridgeRobot
from app.bridge.protocol import CommandReason
from app.bridge.robot_link import STALE_AFTER_S, RobotLink
from app.bridge.watchdog import StaleStateWatchdog
from app.bridge.web_app import create_app
from app.runtime.problems import ProblemKind
from app.runtime.snapshot import RunState
from core.errors import StudioError

if TYPE_CHECKING:
    from app.runtime import Runtime

log = logging.getLogger(__name__)


class BridgeStartError(StudioError, RuntimeError):
    """The hardware bridge could not start serving (the port taken, or the server thread died)."""


class _DenialLogFilter(logging.Filter):
    """uvicorn's sans-I/O WebSocket protocol logs a refused handshake (our 401/409 denial responses) as
    'ASGI callable returned without completing handshake'; the refusal is intended, so drop that line."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "without completing handshake" not in record.getMessage()


DENIAL_LOG_FILTER = _DenialLogFilter()


def _quiet_denials() -> None:
    """Drop uvicorn's line about our intended handshake refusals (once per process; at start, not import)."""
    uvicorn_log = logging.getLogger("uvicorn.error")
    if DENIAL_LOG_FILTER not in uvicorn_log.filters:
        uvicorn_log.addFilter(DENIAL_LOG_FILTER)


def halt_reason(run_state: RunState) -> CommandReason:
    """The reason sent with zero velocity when the run state does not let the robot move."""
    return "emergency_stop" if run_state == RunState.ESTOP else "not_running"


class BridgeServer:
    """The hardware bridge: robot link at `/robot`, operator API at `/api`, OpenAPI at `/openapi.json`."""

    def __init__(self, port: int = 8090, host: str = "127.0.0.1", token: str | None = None,
                 token_file: Path | None = None, stale_after_s: float = STALE_AFTER_S,
                 log_level: str = "warning") -> None:
        self.host = host
        self._port = port
        self._log_level = log_level
        self.token_info = resolve_token(token, token_file)
        self.link = RobotLink(stale_after_s)
        self.robot = BridgeRobot(self.link)
        self.app = create_app(self.token_info, self.link, self.robot)
        self.watchdog = StaleStateWatchdog(self.link, on_stale=self._on_stale)
        self._server: uvicorn.Server | None = None
        self._thread: threading.Thread | None = None

    @property
    def token(self) -> str:
        return self.token_info.value

    @property
    def port(self) -> int:
        """The port served on (the one the OS chose when constructed with port=0)."""
        if self._server is not None and self._server.servers:
            return self._server.servers[0].sockets[0].getsockname()[1]
        return self._port

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    @property
    def robot_url(self) -> str:
        """Where a driver connects."""
        return f"ws://{self.host}:{self.port}/robot"

    def start(self, timeout_s: float = 15.0) -> None:
        """Serve in a background thread; returns once listening (`BridgeStartError`, a RuntimeError, if it cannot)."""
        _quiet_denials()
        config = uvicorn.Config(self.app, host=self.host, port=self._port, log_level=self._log_level,
                                ws="websockets-sansio", lifespan="off")
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, name="bridge-server", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout_s
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise BridgeStartError(f"the hardware bridge could not start on {self.host}:{self._port}")
            time.sleep(0.01)
        self.watchdog.start()
        log.info("hardware bridge on %s (token from %s)", self.url, self.token_info.source)

    def attach(self, runtime: Runtime) -> None:
        """Give the operator API, the stale-state pause and the motion gate this runtime."""
        self.app.state.attachment = RuntimeAttachment(runtime)
        if runtime.backend is self.robot:
            self.robot.motion_allowed = runtime.motion_allowed  # running, or braking after a fault
            self.robot.halt_reason = lambda: halt_reason(runtime.run_state)

    @property
    def attachment(self) -> RuntimeAttachment | None:
        return self.app.state.attachment

    def _on_stale(self, age_s: float) -> None:
        attachment = self.attachment
        if attachment is None or attachment.runtime.backend is not self.robot:
            return
        gone = age_s == float("inf")
        if attachment.running:
            attachment.runtime.pause()
        elif not (gone and attachment.runtime.run_state == RunState.PAUSED):
            return  # (a disconnection after a stale-state pause is still told)
        what = "the driver disconnected" if gone else f"robot state is {age_s * 1e3:.0f} ms old"
        attachment.runtime.problems.record(ProblemKind.STALE_STATE, attachment.runtime.time, what)
        attachment.runtime.notify(f"{what}: zero velocity commanded, run paused (Start resumes)")

    def stop(self, timeout_s: float = 10.0) -> None:
        """Command zero, stop the watchdog, close the driver's link and stop serving."""
        self.robot.stop()
        self.watchdog.stop()
        if self.attachment is not None:
            self.attachment.detach()
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)
            self._thread = None
