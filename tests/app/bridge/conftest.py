"""Real bridges on 127.0.0.1 (uvicorn on a free port), real sockets, the sim driver as a real subprocess."""

from __future__ import annotations

import json
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from websockets.sync.client import ClientConnection, connect

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.auth import TOKEN_ENV
from app.bridge.server import BridgeServer

ROOT = Path(__file__).parents[3]
ZERO_STATE = {"q": [0.0] * 9, "v": [0.0] * 9}
EXAMPLE_SEQUENCE = (ROOT / "tasks" / "examples" / "two_pickups.yaml").read_text()
BAD_SEQUENCE = """name: broken
subtasks:
- name: go
  kind: base
  target: {x: 1.0, y: nope}
"""
"""Line 5 has the error: field subtasks.0.target.y."""


@pytest.fixture
def bridge(tmp_path: Path) -> Iterator[BridgeServer]:
    """A started bridge with its own token, on a port the OS chose."""
    server = BridgeServer(port=0, token=secrets.token_urlsafe(24), token_file=tmp_path / "token")
    server.start()
    yield server
    server.stop()


def auth(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


@pytest.fixture
def raw_driver(bridge: BridgeServer) -> Iterator[ClientConnection]:
    """A hand-driven WebSocket client on the robot link (the welcome already read)."""
    ws = connect(bridge.robot_url, additional_headers=auth(bridge.token), compression=None)
    welcome = json.loads(ws.recv(timeout=5))
    assert welcome["type"] == "welcome"
    yield ws
    ws.close()


def send_state(ws: ClientConnection, t: float, **fields) -> None:
    ws.send(json.dumps({"type": "state", "t": t, **ZERO_STATE, **fields}))


def wait_until(predicate, timeout_s: float = 10.0, period_s: float = 0.01) -> bool:
    """Poll `predicate` until true or `timeout_s` (a test's patience, not a timing requirement)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period_s)
    return bool(predicate())


class DriverProcess:
    """`python -m app.bridge.sim_driver` in its own process, its output collected by a thread."""

    def __init__(self, url: str, token: str, *extra: str) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1", TOKEN_ENV: token}  # never on the command line
        self.proc = subprocess.Popen([sys.executable, "-m", "app.bridge.sim_driver", "--url", url, *extra],
                                     cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def output(self) -> str:
        return "".join(self.lines)

    def signal(self, sig: int) -> None:
        self.proc.send_signal(sig)

    def close(self) -> None:
        end_process(self.proc)


def end_process(proc: subprocess.Popen, timeout_s: float = 20.0) -> None:
    """Terminate `proc` (thawing it first, in case a test froze it); kill it if it does not end."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGCONT)
        proc.terminate()
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture
def start_driver(bridge: BridgeServer) -> Iterator:
    """Start sim drivers on `bridge`; each is connected and streaming when returned; all end at teardown."""
    started: list[DriverProcess] = []

    def start(*extra: str) -> DriverProcess:
        driver = DriverProcess(bridge.robot_url, bridge.token, *extra)
        started.append(driver)
        if not bridge.robot.wait_for_state(90.0):
            driver.close()
            pytest.fail("the sim driver sent no state:\n" + driver.output)
        return driver

    yield start
    for driver in started:
        driver.close()


class Commander:
    """Calls `observe()` and `command(qdot, t)` at 100 Hz in a thread, as the runtime's I/O loop does."""

    def __init__(self, robot, qdot) -> None:
        self.robot, self.qdot = robot, np.asarray(qdot, dtype=float)
        self._stop = threading.Event()
        self.sent = []
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(0.01):
            t = self.robot.observe().state.t
            self.sent.append(self.robot.send(self.qdot, t))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)


FORWARD = [0.3, 0, 0, 0, 0, 0, 0, 0, 0]


@pytest.fixture
def moving_robot(bridge: BridgeServer, start_driver) -> Iterator[tuple[DriverProcess, Commander]]:
    """A sim driver whose base drives forward at 0.3 m/s under 100 Hz commands."""
    driver = start_driver()
    commander = Commander(bridge.robot, FORWARD)
    if not wait_until(lambda: bridge.robot.observe().state.v[0] > 0.25, timeout_s=20):
        commander.stop()
        pytest.fail("the robot did not move:\n" + driver.output)
    yield driver, commander
    commander.stop()


@pytest.fixture
def api(bridge: BridgeServer) -> Iterator[httpx.Client]:
    """An HTTP client of the bridge's operator API that sends the token."""
    with httpx.Client(base_url=bridge.url, headers=auth(bridge.token), timeout=60.0) as client:
        yield client


@pytest.fixture
def sim_runtime(bridge: BridgeServer):
    """A runtime on the embedded simulation (default scene and sequence), attached to the bridge."""
    from app.runtime import Runtime, RuntimeConfig

    runtime = Runtime(RuntimeConfig())
    bridge.attach(runtime)
    yield runtime
    runtime.shutdown()


@pytest.fixture
def bridge_runtime(bridge: BridgeServer):
    """A runtime that drives the bridge's robot (no simulation of its own), attached to the bridge."""
    from app.runtime import Runtime, RuntimeConfig

    runtime = Runtime(RuntimeConfig(), backend=bridge.robot)
    bridge.attach(runtime)
    yield runtime
    runtime.shutdown()


class StateStreamer:
    """Streams zero states at 100 Hz on a raw link from a thread, as a driver would (keeps the state fresh)."""

    def __init__(self, ws: ClientConnection, t0: float = 1.0) -> None:
        self.ws, self.t = ws, t0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(0.01):
            self.t += 0.01
            send_state(self.ws, self.t)

    def __enter__(self) -> StateStreamer:
        send_state(self.ws, self.t)
        self._thread.start()
        return self

    def __exit__(self, *_) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
