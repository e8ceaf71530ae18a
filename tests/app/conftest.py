"""Real servers and a real headless Chromium (Debian's /usr/bin/chromium) for studio tests."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]
ARTIFACTS = ROOT / "test-artifacts"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-sync",
                 "--disable-background-networking", "--disable-component-update",
                 "--use-gl=swiftshader", "--enable-unsafe-swiftshader"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_studio(*args: str) -> tuple[subprocess.Popen, str]:
    """Start `python -m app ARGS --port <free>` and wait for the URL it prints."""
    port = free_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "app", *args, "--port", str(port)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    url, lines, deadline = None, [], time.time() + 90
    while time.time() < deadline and url is None:
        line = proc.stdout.readline()
        if not line and proc.poll() is not None:
            break
        lines.append(line)
        if "open http://" in line:
            url = line.split("open ", 1)[1].split()[0]
    if url is None:
        proc.kill()
        pytest.fail("studio did not start:\n" + "".join(lines))
    # Keep reading: a pipe nobody reads fills at 64 KiB and then blocks whichever studio thread logs next.
    proc.output_lines = lines  # type: ignore[attr-defined]
    threading.Thread(target=lines.extend, args=(proc.stdout,), daemon=True).start()
    return proc, url


def studio_output(proc: subprocess.Popen, last: int = 60) -> str:
    """The last `last` lines the studio started by `start_studio` printed, for a failure's message."""
    return "".join(getattr(proc, "output_lines", [])[-last:])


def stop(proc: subprocess.Popen) -> None:
    proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()


@pytest.fixture
def studio_process() -> Iterator[tuple[subprocess.Popen, str]]:
    """`python -m app` exactly as README command 1 runs it; yields (process, url)."""
    proc, url = start_studio()
    yield proc, url
    stop(proc)


@pytest.fixture
def page():
    """A page in headless Debian Chromium (never a downloaded browser)."""
    if not Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} is missing: run scripts/test.sh, which installs Debian's chromium")
    from playwright.sync_api import sync_playwright

    ARTIFACTS.mkdir(exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        yield page
        browser.close()
