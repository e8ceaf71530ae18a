"""Command line: `python -m app` serves the studio on the embedded MuJoCo simulation."""

from __future__ import annotations

import argparse
import logging
import signal
import threading
from pathlib import Path

from app.runtime import DEFAULT_SCENE, Runtime, RuntimeConfig


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m app", description="Perceptive HTMPC Studio")
    parser.add_argument("--scene", type=Path, default=DEFAULT_SCENE, help="scene YAML (boxes and robot start)")
    parser.add_argument("--host", default="127.0.0.1", help="address to serve on (default: local only)")
    parser.add_argument("--port", type=int, default=8080)
    parser.add_argument("--log-level", default="INFO")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    from app.ui.studio import Studio

    runtime = Runtime(RuntimeConfig(scene=args.scene))
    studio = Studio(runtime, host=args.host, port=args.port)
    runtime.start()
    print(f"Perceptive HTMPC Studio: open {studio.url} in a browser (Ctrl+C to quit)", flush=True)
    done = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: done.set())
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    done.wait()
    runtime.stop()
    studio.close()
    return 0
