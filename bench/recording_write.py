"""Recording's crash window: how long the one write of a flush (chunk + summary + footer, `rolling_summary.py`)
takes, the only moment a kill leaves a torn tail (README: "0.13 ms a second, median, for a 130 KB chunk").

A lockstep run with the object map and both depth cameras' clouds is recorded with the recorder's defaults
(a flush every wall second); the figures are the pwrite times and sizes of those flushes and the share of the
recording's wall time spent inside them.

    python -m bench.recording_write [--quick]
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from app.recording import Recorder
from app.runtime import Runtime, RuntimeConfig
from bench.report import bench_args, write_result
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence

SCENE = Scene((Box("a", (2.0, 0.8, 0.3)), Box("b", (3.0, -1.0, 0.3)), Box("c", (4.5, 0.5, 0.3))))
DRIVE = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=5.5, y=0.0))])


def record(seconds: float, path: Path) -> tuple[Recorder, float]:
    """A lockstep run of `seconds` recorded to `path` (every snapshot); the recorder and its wall seconds."""
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=SCENE, sequence=DRIVE)
    recorder = Recorder(path, sim_time=True)
    rt.subscribe(recorder)
    t0 = time.perf_counter()
    rt.run_lockstep(seconds, publish_every=1, until_done=False)
    recorder.close()
    return recorder, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> None:
    args = bench_args((__doc__ or "recording write").splitlines()[0], argv)
    with tempfile.TemporaryDirectory() as tmp:
        recorder, wall_s = record(6.0 if args.quick else 30.0, Path(tmp) / "run.mcap")
    seconds = np.array([s for s, _ in recorder.writes])
    kb = np.array([b for _, b in recorder.writes]) / 1024
    figures = {"write_ms_median": float(np.median(seconds) * 1e3), "write_ms_max": float(seconds.max() * 1e3),
               "write_kb_median": float(np.median(kb)), "flushes": len(seconds),
               "in_write_share_pct": float(seconds.sum() / wall_s * 100), "snapshots": recorder.count}
    units = {"write_ms_median": "ms", "write_ms_max": "ms", "write_kb_median": "KB", "flushes": "",
             "in_write_share_pct": "%", "snapshots": ""}
    write_result("recording_write", figures, units, {}, quick=args.quick)


if __name__ == "__main__":
    main()
