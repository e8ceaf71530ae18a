"""Reports of a headless run: `report.json` (summary, outcome, the log) and matplotlib figures."""

from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.patches as mpatches  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from app.runtime.problems import ProblemKind, ProblemLog  # noqa: E402
from app.runtime.run_log import RunLog  # noqa: E402
from core.atomic_file import atomic_output, write_text_atomic  # noqa: E402
from core.scene import Box  # noqa: E402


def _draw_boxes(ax, boxes: tuple[Box, ...]) -> None:
    for b in boxes:
        c, s = math.cos(b.yaw), math.sin(b.yaw)
        hx, hy = b.size[0] / 2, b.size[1] / 2
        corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ np.array([[c, s], [-s, c]]) + b.position[:2]
        ax.add_patch(mpatches.Polygon(corners, closed=True, color=(0.76, 0.6, 0.42), alpha=0.8))


def write_report(out_dir: Path, log: RunLog, boxes: tuple[Box, ...], meta: dict,
                 problems: ProblemLog | None = None) -> dict:
    """Write `report.json` (with the problems counted by kind), `path.png` and `timeseries.png` into `out_dir`;
    returns the summary."""
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = {**log.summary(), **{k: v for k, v in meta.items() if isinstance(v, (int, float))}}
    problems = problems or ProblemLog()
    summary.update({f"problems_{k.value}": float(problems.count(k)) for k in ProblemKind})
    report = {"meta": meta, "summary": summary, "problems": problems.to_json(), "log": log.to_json()}
    write_text_atomic(out_dir / "report.json", json.dumps(report, indent=1, allow_nan=True))
    q = np.array(log.q) if log.q else np.zeros((0, 9))
    fig, ax = plt.subplots(figsize=(6, 6))
    _draw_boxes(ax, boxes)
    if len(q):
        ax.plot(q[:, 0], q[:, 1], "-", color="tab:blue", label="base")
        ax.plot(q[0, 0], q[0, 1], "o", color="tab:green", label="start")
        ax.plot(q[-1, 0], q[-1, 1], "s", color="tab:red", label="end")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(meta.get("title", "base path"))
    ax.legend(loc="best")
    with atomic_output(out_dir / "path.png", "wb") as f:
        fig.savefig(f, format="png", dpi=120, bbox_inches="tight")
    plt.close(fig)

    t = np.array(log.t)
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    errs = log.task_errors
    for level in range(max((len(e) for e in errs), default=0)):
        axes[0].plot(t, [e[level] if len(e) > level else np.nan for e in errs], label=f"level {level + 1}")
    axes[0].set_ylabel("task error ‖e‖ (m, rad)")
    axes[0].legend(loc="upper right")
    axes[1].plot(t, log.min_distance_m, color="tab:red")
    axes[1].axhline(0.0, color="k", lw=0.5)
    axes[1].set_ylabel("robot–box distance (m)")
    axes[2].plot(t, log.solve_ms, color="tab:purple")
    axes[2].set_ylabel("solve (ms)")
    axes[2].set_xlabel("sim time (s)")
    fig.tight_layout()
    with atomic_output(out_dir / "timeseries.png", "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    return summary
