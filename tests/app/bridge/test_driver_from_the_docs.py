"""A driver written from docs/bridge.md alone (`doc_driver.py`: no project import, a kinematic robot, a
ray-cast depth camera) runs a sequence to the end through a real bridge and the real runtime, its depth
frames put the box it draws into the map, and nothing it sends is rejected."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pytest

from app.bridge.auth import TOKEN_ENV
from app.bridge.server import BridgeServer
from tasks.sequence_file import parse_sequence
from tests.app.bridge.conftest import ROOT, auth, end_process, wait_until

pytestmark = pytest.mark.wallclock

DRIVER = Path(__file__).with_name("doc_driver.py")
ALLOWED_IMPORTS = {"__future__", "argparse", "json", "math", "os", "signal", "struct", "sys", "threading", "time",
                   "numpy", "websockets"}
BOX = (3.0, 0.6, 0.3)
SEQUENCE = """name: drive and reach
subtasks:
- name: drive
  kind: base
  target: {x: 1.0, y: 0.0, yaw_deg: 0.0}
  tolerance: {position_m: 0.15, orientation_deg: 15.0}
  timeout_s: 60.0
- name: reach
  kind: ee
  target: {position: [1.9, -0.2, 0.8]}
  tolerance: {position_m: 0.05}
  timeout_s: 60.0
  dwell_s: 1.0
  priority: [ee, base]
"""


def test_the_doc_driver_imports_nothing_of_the_project() -> None:
    tree = ast.parse(DRIVER.read_text())
    names = {alias.name.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.Import)
             for alias in node.names}
    names |= {node.module.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert names <= ALLOWED_IMPORTS, names - ALLOWED_IMPORTS


@pytest.mark.slow
def test_a_driver_written_from_the_docs_runs_a_sequence_to_the_end(bridge: BridgeServer, bridge_runtime) -> None:
    bridge_runtime.set_sequence(parse_sequence(SEQUENCE))
    bridge_runtime.start_live()
    driver = subprocess.Popen([sys.executable, str(DRIVER), bridge.robot_url, "--duration", "600", "--box",
                               *map(str, BOX)], cwd=ROOT, env={**os.environ, TOKEN_ENV: bridge.token},
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert bridge.robot.wait_for_state(60.0), "the driver sent no state"
        with httpx.Client(base_url=bridge.url, headers=auth(bridge.token), timeout=30) as api:
            assert wait_until(lambda: not api.get("/api/health").json()["stale"], timeout_s=30)
            assert api.post("/api/run/start").json()["run_state"] == "running"
            deadline, resumed = time.monotonic() + 300, 0
            while time.monotonic() < deadline:
                run_state = api.get("/api/progress").json()["run_state"]
                if run_state == "paused" and api.get("/api/health").json()["stale"] is False:
                    resumed += 1  # a stale-state pause (a loaded machine): resume as the docs tell an operator
                    api.post("/api/run/start")
                elif run_state != "running":
                    break
                time.sleep(0.5)
            progress, health = api.get("/api/progress").json(), api.get("/api/health").json()
        objects = bridge_runtime.map.snapshot().objects
    finally:
        driver.terminate()
        out, err = driver.communicate(timeout=30)
        end_process(driver)
    report = json.loads(out.strip().splitlines()[-1]) if out.strip() else {}
    outcomes = [s["outcome"] for s in progress["subtasks"]]
    assert progress["run_state"] == "finished" and outcomes == ["done", "done"], (progress, err[-2000:])
    assert health["counters"]["rejected"] == {} and report["errors"] == [], (health, report)
    assert health["counters"]["frames"] > 10
    centres = [o.pose[:2, 3] for o in objects]
    assert any(np.linalg.norm(c - np.array(BOX[:2])) < 0.3 for c in centres), f"box not mapped: {centres}"
    assert report["reasons"].get("runtime", 0) > 100
    print(f"\ncommands at the driver: {report['commands']} at {report['command_rate_hz']:.1f} Hz, gaps median "
          f"{report['gap_median_ms']:.1f} ms, p99 {report['gap_p99_ms']:.1f} ms, max {report['gap_max_ms']:.1f} ms; "
          f"reasons {report['reasons']}; resumed after {resumed} stale-state pauses; load {os.getloadavg()[0]:.1f}")
