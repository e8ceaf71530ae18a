"""Ctrl+C on `python -m app` stops the studio cleanly: the terminal signals the whole process group (the map
worker too), and nothing prints a traceback; the map comes back from its process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from tests.app.conftest import ROOT, free_port

pytestmark = pytest.mark.wallclock


def test_ctrl_c_stops_the_studio_and_its_map_worker_without_a_traceback() -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "app", "--port", str(free_port()), "--log-level", "INFO"],
                            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)  # its own process group, as a terminal's foreground job
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr or ()), daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 180
        while not any("the map now runs in the mapping process" in line for line in lines):
            assert proc.poll() is None and time.monotonic() < deadline, "the map never moved:\n" + "".join(lines)
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl+C
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(timeout=5)
    text = "".join(lines)
    assert code == 0, text
    assert "Traceback" not in text and "KeyboardInterrupt" not in text, text
    assert "did not hand its map back" not in text, text
