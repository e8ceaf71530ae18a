"""Command round trip and depth-frame throughput through the hardware bridge.

A real `BridgeServer` (uvicorn on 127.0.0.1) and the reference driver (`python -m app.bridge.sim_driver`,
MuJoCo in real time, two depth cameras at 10 Hz each) in its own process. This process plays the
runtime's I/O loop: `observe()` and `command(qdot, t)` at 100 Hz on the `BridgeRobot`. The round trip
of a command is from `command()` here to the driver's ack arriving back at the bridge. A second run
with a driver that streams no depth (`--cameras ''`) separates the link's own latency from the cost of
rendering and moving 2 × 300 kB frames a tenth of a second.

    python -m bench.bridge_rate [--quick]
"""

from __future__ import annotations

import math
import os
import secrets
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.auth import TOKEN_ENV
from app.bridge.server import BridgeServer
from bench.report import bench_args, percentile, write_result

ROOT = Path(__file__).parents[1]
COMMAND_PERIOD_S = 0.01


def _start_driver(server: BridgeServer, cameras: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-m", "app.bridge.sim_driver", "--url", server.robot_url,
                             "--cameras", cameras, "--log-level", "WARNING"], cwd=ROOT,
                            env={**os.environ, TOKEN_ENV: server.token})
    if not server.robot.wait_for_state(120.0):
        proc.kill()
        raise SystemExit("the sim driver sent no state within 120 s")
    return proc


def _drive(server: BridgeServer, duration_s: float) -> dict[str, list]:
    """Command a gentle arm motion at 100 Hz for `duration_s`; collect round trips and frames."""
    link, robot = server.link, server.robot
    rtt: list[float] = []
    frames: list[str] = []
    acks = link.counts["acks"]
    states0, start = link.counts["states"], time.monotonic()
    next_tick = start
    while time.monotonic() - start < duration_s:
        obs = robot.observe()
        frames.extend(f.camera for f in obs.frames)
        qdot = np.zeros(9)
        qdot[3] = 0.2 * math.sin(2 * math.pi * 0.2 * (time.monotonic() - start))
        robot.command(qdot, obs.state.t)
        new = link.counts["acks"] - acks
        if new:
            rtt.extend(link.rtt_ms()[-new:])
            acks += new
        next_tick += COMMAND_PERIOD_S
        time.sleep(max(0.0, next_tick - time.monotonic()))
    elapsed = time.monotonic() - start
    return {"rtt": rtt, "frames": frames, "elapsed": [elapsed], "states": [link.counts["states"] - states0]}


def _measure(cameras: str, duration_s: float) -> dict[str, list]:
    """A fresh bridge and driver streaming `cameras` ('' none); 2 s of warm-up, then `duration_s` measured."""
    with tempfile.TemporaryDirectory() as tmp:
        server = BridgeServer(port=0, token=secrets.token_urlsafe(24), token_file=Path(tmp) / "token")
        server.start()
        driver = _start_driver(server, cameras)
        try:
            _drive(server, 2.0)  # warm-up: renderers, validators, TCP windows
            return _drive(server, duration_s)
        finally:
            driver.send_signal(signal.SIGTERM)
            driver.wait(timeout=20)
            server.stop()


def main(argv: list[str] | None = None) -> int:
    args = bench_args(__doc__.splitlines()[0], argv)
    run = _measure("hand,base", 15.0 if args.quick else 120.0)
    bare = _measure("", 8.0 if args.quick else 60.0)
    elapsed = run["elapsed"][0]
    rtt = run["rtt"]
    figures = {
        "command_rtt_median_ms": percentile(rtt, 50),
        "command_rtt_p99_ms": percentile(rtt, 99),
        "depth_frames_per_s": len(run["frames"]) / elapsed,
        "state_rate_hz": run["states"][0] / elapsed,
        "commands_acked_per_s": len(rtt) / elapsed,
        "hand_frames_per_s": run["frames"].count("hand") / elapsed,
        "base_frames_per_s": run["frames"].count("base") / elapsed,
        "command_rtt_median_no_depth_ms": percentile(bare["rtt"], 50),
        "command_rtt_p99_no_depth_ms": percentile(bare["rtt"], 99),
    }
    units = {"command_rtt_median_ms": "ms", "command_rtt_p99_ms": "ms", "depth_frames_per_s": "1/s",
             "state_rate_hz": "Hz", "commands_acked_per_s": "1/s", "hand_frames_per_s": "1/s",
             "base_frames_per_s": "1/s", "command_rtt_median_no_depth_ms": "ms", "command_rtt_p99_no_depth_ms": "ms"}
    targets = {"command_rtt_median_ms": "<= 5", "command_rtt_p99_ms": "<= 20", "depth_frames_per_s": ">= 10",
               "state_rate_hz": "50–100", "commands_acked_per_s": ">= 95"}
    write_result("bridge_rate", figures, units, targets, quick=args.quick,
                 extra={"duration_s": elapsed, "rtt_samples": len(rtt), "no_depth_rtt_samples": len(bare["rtt"])})
    return 0


if __name__ == "__main__":
    sys.exit(main())
