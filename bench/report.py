"""Writing benchmark results as docs/design.md, "Benchmarks" asks: a table and `bench/results/<name>.json`."""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from core.atomic_file import write_text_atomic

RESULTS_DIR = Path(__file__).parent / "results"


def machine() -> dict[str, object]:
    """CPU model, core count, Python version and load average (1, 5, 15 min: timings on a shared machine are
    only comparable at similar load) of this machine."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "load_average": [round(x, 2) for x in os.getloadavg()]}


def bench_args(description: str, argv: list[str] | None = None,
               extra: Callable[[argparse.ArgumentParser], None] | None = None) -> argparse.Namespace:
    """The common command line: `--quick` for the short run (`extra` adds a bench's own options)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="short run (under a minute) with the same figures")
    if extra is not None:
        extra(parser)
    return parser.parse_args(argv if argv is not None else sys.argv[1:])


def percentile(samples: list[float] | np.ndarray, q: float) -> float:
    """q-th percentile of the finite samples (NaN when there are none)."""
    a = np.asarray(samples, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.percentile(a, q)) if a.size else float("nan")


def write_result(name: str, figures: dict[str, float], units: dict[str, str], targets: dict[str, str] | None = None,
                 quick: bool = False, extra: dict | None = None) -> Path:
    """Print the figures as a table and write `bench/results/<name>.json`; returns its path."""
    table = Table(title=f"{name}{' (quick)' if quick else ''}")
    for col in ("figure", "value", "unit", "target"):
        table.add_column(col)
    targets = targets or {}
    for key, value in figures.items():
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value), units.get(key, ""),
                      targets.get(key, ""))
    Console().print(table)
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    payload = {
        "bench": name,
        "when": dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "quick": quick,
        "machine": machine(),
        "figures": {k: float(v) for k, v in figures.items()},
        "units": units,
        "targets": targets,
    }
    if extra:
        payload["extra"] = extra
    path = RESULTS_DIR / f"{name}.json"
    write_text_atomic(path, json.dumps(payload, indent=2))
    return path
