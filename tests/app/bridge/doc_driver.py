"""A robot driver written from docs/bridge.md alone (no import of this project): a kinematic robot that
integrates the commanded joint velocities, and a forward-looking depth camera on its base that sees the
floor and one box by ray casting. Used by test_driver_from_the_docs.py; runnable by hand too:

    HTMPC_BRIDGE_TOKEN=... python tests/app/bridge/doc_driver.py ws://127.0.0.1:8090/robot --duration 60

At exit (the duration, SIGTERM or the link closing) it prints one JSON line: what it received (commands
by reason, rejections) and the command inter-arrival times it measured.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import struct
import sys
import threading
import time

import numpy as np
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

READY_Q = [0.0, 0.0, 0.0, 0.0, -1.6, 2.2, -0.2, math.pi / 2, math.pi]  # docs: "Ready pose"
COMMAND_TIMEOUT_S = 0.25
CAMERA_IN_BASE = (0.50, 0.0, 0.38)  # this robot's base camera: 0.5 m ahead, 0.38 m up, pitched 12° down
CAMERA_PITCH = math.radians(12.0)
W, H, F = 80, 60, 60.0
K = [[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]]
RANGE_M = 3.0


def camera_pose(q: list[float]) -> np.ndarray:
    """T_world_camera (OpenCV axes: x right, y down, z forward) of the base camera for base pose q[:3]."""
    c, s = math.cos(q[2]), math.sin(q[2])
    R_world_base = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    cp, sp = math.cos(CAMERA_PITCH), math.sin(CAMERA_PITCH)
    forward, right = np.array([cp, 0.0, -sp]), np.array([0.0, -1.0, 0.0])
    R_base_camera = np.column_stack([right, np.cross(forward, right), forward])
    T = np.eye(4)
    T[:3, :3] = R_world_base @ R_base_camera
    T[:3, 3] = np.array([q[0], q[1], 0.0]) + R_world_base @ np.array(CAMERA_IN_BASE)
    return T


def render_depth(T: np.ndarray, box_lo: np.ndarray, box_hi: np.ndarray) -> np.ndarray:
    """Planar depth (m, float32, 0 = no return) of the floor z = 0 and one axis-aligned box."""
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    rays_cam = np.stack([(u - K[0][2]) / F, (v - K[1][2]) / F, np.ones_like(u, dtype=float)], axis=-1)
    d = rays_cam @ T[:3, :3].T  # world direction per pixel, scaled so the optical-axis component is 1
    p = T[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(d[..., 2] < 0.0, -p[2] / d[..., 2], np.inf)
        t1, t2 = (box_lo - p) / d, (box_hi - p) / d
        t_near = np.nanmax(np.minimum(t1, t2), axis=-1)
        t_far = np.nanmin(np.maximum(t1, t2), axis=-1)
    t_box = np.where((t_near <= t_far) & (t_near > 0.0), t_near, np.inf)
    depth = np.minimum(t_floor, t_box)
    return np.where(depth <= RANGE_M, depth, 0.0).astype("<f4")


def depth_message(t: float, T: np.ndarray, depth: np.ndarray) -> bytes:
    header = json.dumps({"type": "depth", "t": t, "camera": "base", "width": W, "height": H, "encoding": "float32_m",
                         "K": K, "T_world_camera": T.tolist(), "range_m": RANGE_M}).encode()
    return b"HDF1" + struct.pack("<I", len(header)) + header + depth.tobytes()


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("url")
    parser.add_argument("--duration", type=float, default=120.0)
    parser.add_argument("--box", type=float, nargs=3, default=[3.0, 0.6, 0.3], help="box centre (m), 0.6 m cube")
    args = parser.parse_args()
    box = np.array(args.box)
    box_lo, box_hi = box - 0.3, box + 0.3

    ws = connect(args.url, additional_headers={"Authorization": f"Bearer {os.environ['HTMPC_BRIDGE_TOKEN']}"},
                 max_size=2**24, compression=None)
    welcome = json.loads(ws.recv(timeout=10))
    assert welcome["type"] == "welcome", welcome
    ws.send(json.dumps({"type": "hello", "driver": "doc-driver", "protocol": 1}))

    lock = threading.Lock()
    latest = {"qdot": [0.0] * 9, "at": time.monotonic(), "open": True}
    arrivals: list[float] = []
    reasons: dict[str, int] = {}
    errors: list[str] = []
    t0 = time.monotonic()

    def receive() -> None:
        try:
            for text in ws:
                msg = json.loads(text)
                now = time.monotonic()
                if msg["type"] == "command":  # ack at once (seq is an integer), keep only the newest
                    ws.send(json.dumps({"type": "ack", "seq": msg["seq"], "t": now - t0}))
                    with lock:
                        latest.update(qdot=msg["qdot"], at=now)
                        arrivals.append(now)
                        reasons[msg["reason"]] = reasons.get(msg["reason"], 0) + 1
                elif msg["type"] == "error":
                    errors.append(f"{msg['code']}: {msg['message']}")
        except ConnectionClosed:
            pass
        with lock:
            latest.update(qdot=[0.0] * 9, open=False)  # link closed: stop

    threading.Thread(target=receive, daemon=True).start()
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    q, v = list(READY_Q), [0.0] * 9
    last_step, next_frame, deadline = time.monotonic(), 0.0, time.monotonic() + args.duration
    while time.monotonic() < deadline and not stop.is_set():
        now = time.monotonic()
        with lock:
            if not latest["open"]:
                break
            fresh = now - latest["at"] < COMMAND_TIMEOUT_S
            v = [float(x) for x in latest["qdot"]] if fresh else [0.0] * 9
        dt, last_step = now - last_step, now
        q = [qi + vi * dt for qi, vi in zip(q, v, strict=True)]  # the "hardware": a perfect integrator
        t = now - t0
        ws.send(json.dumps({"type": "state", "t": t, "q": q, "v": v}))
        if t >= next_frame:  # 5 Hz depth
            T = camera_pose(q)
            ws.send(depth_message(t, T, render_depth(T, box_lo, box_hi)))
            next_frame = t + 0.2
        time.sleep(max(0.0, 0.01 - (time.monotonic() - now)))
    ws.close()
    gaps = np.diff(arrivals) * 1e3 if len(arrivals) > 1 else np.zeros(1)
    span = arrivals[-1] - arrivals[0] if len(arrivals) > 1 else 0.0
    print(json.dumps({"commands": len(arrivals), "reasons": reasons, "errors": errors, "final_q": q,
                      "command_rate_hz": (len(arrivals) - 1) / span if span else 0.0,
                      "gap_median_ms": float(np.median(gaps)), "gap_p99_ms": float(np.percentile(gaps, 99)),
                      "gap_max_ms": float(gaps.max())}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
