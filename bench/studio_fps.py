"""The studio page in Debian's headless chromium (software WebGL, no GPU) while a sequence runs live:
frames per second the page reaches, what the studio sends it per second, and snapshots drawn per second.
The studio's view (light meshes, no shadows, no environment map) is measured against the detailed one
(visual meshes, shadows, image-based lighting), alternating, in one run.

    python -m bench.studio_fps [--quick] [--base-camera-hz 20]

`--base-camera-hz` runs the studio's base camera at another rate (the paper's 10 Hz by default): whether the map keeps
it with the page open is `frames_skipped_per_s`.
"""

from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import core.sim  # noqa: F401  (GL backend first)
from app.runtime import Runtime, RuntimeConfig
from app.ui.studio import DETAILED_VIEW, Studio, ViewSettings
from bench.report import bench_args, write_result
from core.params import CameraParams, SimParams
from core.scene import random_scene
from tasks.sequence_file import EXAMPLES_DIR, load_sequence

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--use-gl=swiftshader", "--enable-unsafe-swiftshader",
                 "--no-first-run", "--disable-background-networking", "--disable-component-update"]
FRAMES = """(ms) => new Promise((done) => {
  let n = 0; const t0 = performance.now();
  const tick = () => {
    n++;
    if (performance.now() - t0 < ms) requestAnimationFrame(tick); else done([n, performance.now() - t0]);
  };
  requestAnimationFrame(tick);
})"""
"""Counts requestAnimationFrame callbacks: the frames the page renders (three.js draws once per frame)."""


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def measure(browser, view: ViewSettings, seconds: float, base_camera_hz: float = CameraParams().rate_hz
            ) -> dict[str, float]:
    """One page on a studio with `view` while the navigation example runs live (its base camera at `base_camera_hz`):
    fps, bytes and messages/s received on its WebSocket, snapshots drawn/s, CPU seconds of this
    process per wall second, and depth frames the map skipped per second (a camera rate the map could not keep)."""
    sim = SimParams()
    sim = replace(sim, base_camera=replace(sim.base_camera, rate_hz=base_camera_hz))
    rt = Runtime(RuntimeConfig(map_kind="object", sim=sim), scene=random_scene(0),
                 sequence=load_sequence(EXAMPLES_DIR / "navigation_through_boxes.yaml"))
    studio = Studio(rt, port=_free_port(), view=view)
    received = {"bytes": 0, "messages": 0}

    def on_socket(ws) -> None:
        def count(payload) -> None:
            received["bytes"] += len(payload)
            received["messages"] += 1
        ws.on("framereceived", count)

    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.on("websocket", on_socket)
    try:
        page.set_default_timeout(120_000)
        page.goto(studio.url)
        page.get_by_text("EMERGENCY STOP").first.wait_for()
        page.wait_for_selector("canvas")
        rt.start_live()
        rt.start()
        page.wait_for_timeout(3000)  # meshes arrive, the run gets going
        draws0, bytes0, msgs0 = studio.draws, received["bytes"], received["messages"]
        skipped0 = rt.closed_loop.frames_skipped
        cpu0, t0 = time.process_time(), time.perf_counter()
        frames, ms = page.evaluate(FRAMES, seconds * 1e3)
        wall = time.perf_counter() - t0
        return {"fps": frames * 1e3 / ms, "kib_per_s": (received["bytes"] - bytes0) / 1024 / wall,
                "messages_per_s": (received["messages"] - msgs0) / wall, "draws_per_s": (studio.draws - draws0) / wall,
                "server_cpu": (time.process_time() - cpu0) / wall,
                "frames_skipped_per_s": (rt.closed_loop.frames_skipped - skipped0) / wall}
    finally:
        page.close()
        rt.shutdown()
        studio.close()


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0], argv, lambda parser: parser.add_argument(
        "--base-camera-hz", type=float, default=CameraParams().rate_hz, help="the base camera's rate (Hz)"))
    if not Path(CHROMIUM).exists():
        raise SystemExit(f"{CHROMIUM} is missing: scripts/test.sh installs Debian's chromium")
    from playwright.sync_api import sync_playwright

    seconds, rounds = (5.0, 1) if args.quick else (10.0, 3)
    light, detailed = [], []
    load0 = os.getloadavg()[0]
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            for _ in range(rounds):  # alternate, so both see the same machine
                light.append(measure(browser, ViewSettings(), seconds, args.base_camera_hz))
                detailed.append(measure(browser, DETAILED_VIEW, seconds, args.base_camera_hz))
        finally:
            browser.close()

    def med(rows: list[dict[str, float]], key: str) -> float:
        return float(np.median([r[key] for r in rows]))

    figures = {"page_fps": med(light, "fps"), "page_fps_detailed": med(detailed, "fps"),
               "fps_ratio_vs_detailed": med(light, "fps") / max(med(detailed, "fps"), 1e-9),
               "ui_update_hz_with_page": med(light, "draws_per_s"), "sent_kib_per_s": med(light, "kib_per_s"),
               "sent_messages_per_s": med(light, "messages_per_s"), "server_cpu_per_s": med(light, "server_cpu"),
               "frames_skipped_per_s": med(light, "frames_skipped_per_s"), "base_camera_hz": args.base_camera_hz,
               "load_average_1min": load0}
    units = {"page_fps": "Hz", "page_fps_detailed": "Hz", "fps_ratio_vs_detailed": "x",
             "ui_update_hz_with_page": "Hz", "sent_kib_per_s": "KiB/s", "sent_messages_per_s": "1/s",
             "server_cpu_per_s": "s/s", "frames_skipped_per_s": "1/s", "base_camera_hz": "Hz",
             "load_average_1min": ""}
    targets = {"page_fps": ">= 10", "ui_update_hz_with_page": ">= 10"}
    write_result("studio_fps", figures, units, targets, quick=args.quick,
                 extra={"rounds": {"light": light, "detailed": detailed}})


if __name__ == "__main__":
    main()
