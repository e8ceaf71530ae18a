"""The files of an experiment report: `<name>.json`, figures (PNG) and `README.md` in `reports/<name>/`.

The JSON holds the run's settings, the machine, the commit, every trial's result and the summary
figures; the markdown puts our figures beside the paper's (docs/method.md, "What the paper measured").
The commit is the one the trials ran on, flagged '+dirty' when the code differed from it; a report rewritten
with `--report-only` keeps the run's commit and names its own beside it.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import logging
import math
import subprocess
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.patches as mpatches  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from bench.experiments.paths import ROOT  # noqa: E402
from bench.report import machine  # noqa: E402
from core.atomic_file import atomic_output, write_text_atomic  # noqa: E402
from core.scene import Box  # noqa: E402

log = logging.getLogger(__name__)


def git_commit() -> str:
    """The checkout's HEAD commit (with '+dirty' when files other than the reports differ from it, new
    files not ignored included: a report written by an earlier experiment of the same checkout is not a
    change to the code), or 'unknown'."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=normal", "--", ".", ":!reports"],
                               cwd=ROOT, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"
    return f"{head}+dirty" if dirty else (head or "unknown")


@dataclass(frozen=True)
class RunStamp:
    """Where and when an experiment's trials ran."""

    commit: str
    when: str
    machine: dict
    params_file: str | None = None
    """The `--params` file of tunables the trials ran with (None: the experiment's defaults)."""

    @classmethod
    def now(cls, params_file: str | None = None) -> RunStamp:
        return cls(git_commit(), dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), machine(), params_file)

    @classmethod
    def saved(cls, out_dir: Path, name: str) -> RunStamp:
        """The stamp of the run saved in `<out_dir>/<name>.json` (what `--report-only` reports on)."""
        data = json.loads((out_dir / f"{name}.json").read_text(encoding="utf-8"))
        return cls(data.get("commit", "unknown"), data.get("when", "unknown"), data.get("machine", {}),
                   data.get("params_file"))

    @property
    def dirty(self) -> bool:
        return self.commit.endswith("+dirty") or self.commit == "unknown"


def _clean(value):
    """JSON-able copy: numpy scalars and arrays to Python, NaN and inf kept as None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    return value


def write_json(out_dir: Path, name: str, settings: dict, figures: dict, trials: list[dict],
               quick: bool, extra: dict | None = None, stamp: RunStamp | None = None) -> Path:
    """`<out_dir>/<name>.json`: settings, machine, commit (of the run: `stamp`, default now), summary figures
    and every trial."""
    out_dir.mkdir(parents=True, exist_ok=True)
    stamp = stamp or RunStamp.now()
    if stamp.dirty:
        log.warning("%s: the trials ran on %s: uncommitted changes, the report says so", name, stamp.commit)
    payload = {
        "experiment": name,
        "when": stamp.when,
        "quick": quick,
        "commit": stamp.commit,
        "machine": stamp.machine,
        **({"params_file": stamp.params_file} if stamp.params_file else {}),
        "settings": settings,
        "figures": figures,
        "trials": [{k: v for k, v in t.items() if k != "traceback"} for t in trials],
        "errors": [t for t in trials if "error" in t],
        **(extra or {}),
    }
    path = out_dir / f"{name}.json"
    write_text_atomic(path, json.dumps(_clean(payload), indent=1))
    return path


def fmt(value, digits: int = 2) -> str:
    """A table cell: numbers rounded, NaN/None as '–', booleans as yes/no."""
    if value is None:
        return "–"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "–" if not math.isfinite(value) else f"{value:.{digits}f}"
    return str(value)


def md_table(headers: Sequence[str], rows: Iterable[Sequence]) -> str:
    """A GitHub markdown table."""
    lines = ["| " + " | ".join(headers) + " |", "| " + " | ".join("---" for _ in headers) + " |"]
    lines += ["| " + " | ".join(fmt(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def write_markdown(out_dir: Path, name: str, title: str, sections: list[tuple[str, str]], quick: bool,
                   options: str = "") -> Path:
    """`<out_dir>/README.md`: title, the command that made it (with `options` beyond --quick) and the run's
    commit and machine (from `<name>.json` beside it), then (heading, body) sections."""
    stamp = RunStamp.saved(out_dir, name)
    options = " ".join(o for o in (options, f"--params {stamp.params_file}" if stamp.params_file else "") if o)
    command = f"python -m bench.experiments.{name}{' --quick' if quick else ''}{' ' + options if options else ''}"
    when = stamp.when.replace("T", " ")
    cpu, cores = stamp.machine.get("cpu", "unknown CPU"), stamp.machine.get("cores", "?")
    head = [f"# {title}", "",
            f"Made by `{command}`{' (quick smoke variant: few trials, not the full figures)' if quick else ''} "
            f"on commit `{stamp.commit}`, {when[:16]} UTC, {cpu} ({cores} cores). Simulated, lockstep, seeds fixed."]
    if stamp.dirty:
        head.append(f"**The code had uncommitted changes** (`{stamp.commit}`): these figures may not come from "
                    "that commit.")
    report_commit = git_commit()
    if report_commit != stamp.commit:
        head.append(f"This report was written on commit `{report_commit}`, from those trials (`--report-only`, or the "
                    "tree changed while they ran: their code was imported at the start).")
    head.append("")
    body = [f"## {h}\n\n{b.strip()}\n" for h, b in sections]
    path = out_dir / "README.md"
    write_text_atomic(path, "\n".join(head + body))
    return path


def save_figure(fig: plt.Figure, out_dir: Path, name: str) -> str:
    """Save as `<out_dir>/<name>.png`, close it, return the file name (for the markdown)."""
    fig.tight_layout()
    with atomic_output(out_dir / f"{name}.png", "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    return f"{name}.png"


def draw_boxes(ax: plt.Axes, boxes: Iterable[Box], colour: str = "tan") -> None:
    """Footprints of boxes (rotated rectangles) on a top view."""
    for b in boxes:
        ax.add_patch(mpatches.Rectangle((b.position[0] - b.size[0] / 2, b.position[1] - b.size[1] / 2), b.size[0],
                                        b.size[1], angle=math.degrees(b.yaw), rotation_point="center",
                                        color=colour, alpha=0.8))


def rate(trials: list[dict], key: str) -> float:
    """Fraction of trials (those that did not crash) where `key` is true."""
    ok = [t for t in trials if "error" not in t]
    return float(np.mean([bool(t.get(key)) for t in ok])) if ok else math.nan


def stat(trials: list[dict], key: str, how: str = "median") -> float:
    """Median (or mean, min, max) of the finite values of `key` over trials that did not crash."""
    vals = np.array([t.get(key) for t in trials if "error" not in t and t.get(key) is not None], float)
    vals = vals[np.isfinite(vals)]
    if not len(vals):
        return math.nan
    return float({"median": np.median, "mean": np.mean, "min": np.min, "max": np.max}[how](vals))


def finish_experiment(args: argparse.Namespace, name: str, results: list[dict], figures: dict[str, float],
                      settings: dict, draw: Callable[[Path], list[str]], write: Callable[[list[str]], None],
                      show: Callable[[str], bool] = lambda key: True) -> dict[str, float]:
    """The end every experiment's `main` shares: figures drawn into `args.out` (`draw` returns the PNG names),
    `<name>.json` with the run's stamp (`args.stamp`, taken by `experiment_args` before the trials; the saved run's
    for `--report-only`), the markdown (`write(pngs)`),
    and the figures `show` selects printed. Returns the figures."""
    stamp = RunStamp.saved(args.out, name) if args.report_only else args.stamp  # taken when the run began
    args.out.mkdir(parents=True, exist_ok=True)
    pngs = draw(args.out)
    write_json(args.out, name, settings, figures, results, args.quick, stamp=stamp)
    write(pngs)
    print("\n".join(f"{k}: {fmt(v)}" for k, v in figures.items() if show(k)))
    return figures
