"""End to end: the studio (`python -m app --backend bridge`) and the sim driver, two processes talking over
real sockets, complete a two-subtask sequence started through the operator API."""

from __future__ import annotations

import os
import secrets
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from tests.app.bridge.conftest import ROOT, DriverProcess, auth, end_process, wait_until

pytestmark = pytest.mark.wallclock

SCENE = ROOT / "core" / "scenes" / "default.yaml"
SEQUENCE = f"""name: drive and reach
scene: {SCENE}
subtasks:
- name: drive between the boxes
  kind: base
  target: {{x: 1.0, y: 0.0, yaw_deg: 0.0}}
  tolerance: {{position_m: 0.15, orientation_deg: 15.0}}
  timeout_s: 60.0
- name: reach forward
  kind: ee
  target: {{position: [1.9, -0.2, 0.8]}}
  tolerance: {{position_m: 0.05}}
  timeout_s: 60.0
  dwell_s: 1.0
  priority: [ee, base]
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Studio:
    """`python -m app --backend bridge` in its own process."""

    def __init__(self, sequence: Path, token: str) -> None:
        self.bridge_port, ui_port = _free_port(), _free_port()
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "HTMPC_BRIDGE_TOKEN": token}
        self.proc = subprocess.Popen([sys.executable, "-m", "app", "--backend", "bridge", "--bridge-port",
                                      str(self.bridge_port), "--port", str(ui_port), "--sequence", str(sequence)],
                                     cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        threading.Thread(target=lambda: self.lines.extend(self.proc.stdout), daemon=True).start()

    @property
    def output(self) -> str:
        return "".join(self.lines)

    def close(self) -> None:
        end_process(self.proc)


@pytest.fixture
def studio_and_driver(tmp_path: Path) -> Iterator[tuple[Studio, DriverProcess, str]]:
    token = secrets.token_urlsafe(24)
    sequence = tmp_path / "drive_and_reach.yaml"
    sequence.write_text(SEQUENCE)
    studio = Studio(sequence, token)
    driver = None
    try:
        if not wait_until(lambda: "open http://" in studio.output or studio.proc.poll() is not None, 120):
            pytest.fail("the studio did not start:\n" + studio.output)
        assert studio.proc.poll() is None, studio.output
        driver = DriverProcess(f"ws://127.0.0.1:{studio.bridge_port}/robot", token, "--scene", str(SCENE))
        yield studio, driver, token
    finally:
        if driver is not None:
            driver.close()
        studio.close()


@pytest.mark.slow
def test_studio_on_the_bridge_completes_a_two_subtask_sequence(studio_and_driver) -> None:
    studio, driver, token = studio_and_driver
    with httpx.Client(base_url=f"http://127.0.0.1:{studio.bridge_port}", headers=auth(token), timeout=30) as api:
        def fresh() -> bool:
            health = api.get("/api/health").json()
            return health["driver_connected"] and not health["stale"]

        assert wait_until(fresh, timeout_s=120, period_s=0.2), driver.output + "\n--- studio log ---\n" + studio.output
        started = api.post("/api/run/start").json()
        assert started["run_state"] == "running", (started, studio.output)
        deadline = time.monotonic() + 300
        progress = api.get("/api/progress").json()
        while progress["run_state"] == "running" and time.monotonic() < deadline:
            time.sleep(0.5)
            progress = api.get("/api/progress").json()
        health = api.get("/api/health").json()
    outcomes = [s["outcome"] for s in progress["subtasks"]]
    assert progress["run_state"] == "finished" and outcomes == ["done", "done"], (
        f"{progress}\n{health}\n--- studio log (all of it) ---\n{studio.output}")
    assert health["counters"]["rejected"] == {} and health["counters"]["frames"] > 0
    assert token not in studio.output and token[:4] in studio.output, "the token is printed masked, never whole"
