"""What a run leaves behind: one row per control period, summaries, events (faults), and the report files.

Memory stays bounded however long a run lasts: the log keeps the newest `window_rows` rows in memory and
appends older ones, a chunk at a time, to a spill file (JSON lines in the temporary folder, removed with
the log). The column properties (`t`, `q`, …), `summary()` and `to_json()` read the spill file back, so
reports cover the whole run.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from core.atomic_file import write_text_atomic
from core.types import Plan, RobotState

COLUMNS = ("t", "q", "v", "qdot", "task_errors", "solve_ms", "plan_status", "min_distance_m", "collisions",
           "run_state", "subtask", "timings_ms")
ARRAY_COLUMNS = ("q", "v", "qdot")
WINDOW_ROWS = 3000
"""Rows kept in memory: 5 minutes at the 10 Hz control rate."""


@dataclass(frozen=True)
class RunEvent:
    """Something that happened to the run at sim time `t` (s): kind 'fault', with the reason."""

    t: float
    kind: str
    detail: str


class RunLog:
    """Rows recorded at the control rate by the runtime; the newest `window_rows` stay in memory."""

    def __init__(self, window_rows: int = WINDOW_ROWS, spill_dir: Path | None = None) -> None:
        self.window_rows = max(1, int(window_rows))
        self._spill_dir = spill_dir
        self._window: dict[str, list[Any]] = {c: [] for c in COLUMNS}
        self._spill_path: Path | None = None
        self._spilled_rows = 0
        self._finalizer: weakref.finalize | None = None
        self.events: list[RunEvent] = []

    # --- recording -----------------------------------------------------------------------------------

    def record(self, state: RobotState, plan: Plan | None, min_distance_m: float, collisions: int, run_state,
               subtask: int, qdot: np.ndarray, timings_ms: dict[str, float]) -> None:
        w = self._window
        w["t"].append(float(state.t))
        w["q"].append(state.q.copy())
        w["v"].append(state.v.copy())
        w["qdot"].append(np.asarray(qdot, float).copy())
        w["task_errors"].append(tuple(plan.task_errors) if plan is not None else ())
        w["solve_ms"].append(float(sum(plan.solve_ms)) if plan is not None else math.nan)
        w["plan_status"].append(plan.status.value if plan is not None else "none")
        w["min_distance_m"].append(float(min_distance_m))
        w["collisions"].append(int(collisions))
        w["run_state"].append(str(run_state))
        w["subtask"].append(int(subtask))
        w["timings_ms"].append(dict(timings_ms))
        chunk = max(1, self.window_rows // 4)
        if len(w["t"]) >= self.window_rows + chunk:
            self._spill(chunk)

    def event(self, t: float, kind: str, detail: str) -> None:
        """Note an event (a fault and its reason) at sim time t."""
        self.events.append(RunEvent(float(t), kind, detail))

    def _spill(self, n: int) -> None:
        """Append the oldest n rows of the window to the spill file and drop them from memory."""
        if self._spill_path is None:
            fd, name = tempfile.mkstemp(prefix="htmpc-runlog-", suffix=".jsonl", dir=self._spill_dir)
            os.close(fd)
            self._spill_path = Path(name)
            self._finalizer = weakref.finalize(self, _unlink, self._spill_path)
        w = self._window
        with self._spill_path.open("a", encoding="utf-8") as f:
            for i in range(n):
                row = {c: (w[c][i].tolist() if c in ARRAY_COLUMNS else w[c][i]) for c in COLUMNS}
                f.write(json.dumps(row, allow_nan=True) + "\n")
        for c in COLUMNS:
            del w[c][:n]
        self._spilled_rows += n

    def close(self) -> None:
        """Remove the spill file (the log keeps only its in-memory window afterwards)."""
        if self._finalizer is not None:
            self._finalizer()

    # --- reading -------------------------------------------------------------------------------------

    def __len__(self) -> int:
        return self._spilled_rows + len(self._window["t"])

    @property
    def rows_in_memory(self) -> int:
        return len(self._window["t"])

    def column(self, name: str) -> list[Any]:
        """Every row's value of column `name`, oldest first (spilled rows read back from disk)."""
        if name not in self._window:
            raise KeyError(f"no column {name!r}; columns: {COLUMNS}")
        if not self._spilled_rows or self._spill_path is None:
            return self._window[name]
        convert = np.asarray if name in ARRAY_COLUMNS else (tuple if name == "task_errors" else _same)
        with self._spill_path.open(encoding="utf-8") as f:
            disk = [convert(json.loads(line)[name]) for line in f]
        return disk + self._window[name]

    t = property(lambda self: self.column("t"))
    q = property(lambda self: self.column("q"))
    v = property(lambda self: self.column("v"))
    qdot = property(lambda self: self.column("qdot"))
    task_errors = property(lambda self: self.column("task_errors"))
    solve_ms = property(lambda self: self.column("solve_ms"))
    plan_status = property(lambda self: self.column("plan_status"))
    min_distance_m = property(lambda self: self.column("min_distance_m"))
    collisions = property(lambda self: self.column("collisions"))
    run_state = property(lambda self: self.column("run_state"))
    subtask = property(lambda self: self.column("subtask"))
    timings_ms = property(lambda self: self.column("timings_ms"))

    def base_path_length_m(self) -> float:
        q = self.q
        if len(q) < 2:
            return 0.0
        xy = np.array([qi[:2] for qi in q])
        return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())

    def summary(self) -> dict[str, float]:
        """Figures of the run: duration, path length, clearance, collisions, solve times, speeds, faults."""
        t, v, collisions, status = self.t, self.v, self.collisions, self.plan_status
        solve = np.array([s for s in self.solve_ms if not math.isnan(s)])
        dist = np.array([d for d in self.min_distance_m if not math.isnan(d)])
        speed = np.array([np.hypot(*vi[:2]) for vi in v]) if v else np.zeros(1)
        return {
            "duration_s": (t[-1] - t[0]) if t else 0.0,
            "base_path_length_m": self.base_path_length_m(),
            "min_clearance_m": float(dist.min()) if len(dist) else math.nan,
            "collisions": float(collisions[-1]) if collisions else 0.0,
            "solve_ms_median": float(np.median(solve)) if len(solve) else math.nan,
            "solve_ms_p99": float(np.percentile(solve, 99)) if len(solve) else math.nan,
            "max_base_speed_mps": float(speed.max()),
            "mean_base_speed_mps": float(speed.mean()),
            "fallback_steps": float(sum(s not in ("ok", "ok_with_slack", "none") for s in status)),
            "faults": float(sum(e.kind == "fault" for e in self.events)),
        }

    def to_json(self) -> dict:
        return {
            "summary": self.summary(),
            "events": [{"t": e.t, "kind": e.kind, "detail": e.detail} for e in self.events],
            "t": self.t,
            "q": [q.tolist() for q in self.q],
            "task_errors": [list(e) for e in self.task_errors],
            "solve_ms": self.solve_ms,
            "plan_status": self.plan_status,
            "min_distance_m": self.min_distance_m,
            "collisions": self.collisions,
            "run_state": self.run_state,
            "subtask": self.subtask,
        }

    def save(self, path: Path) -> None:
        write_text_atomic(path, json.dumps(self.to_json(), allow_nan=True))


def _same(x: Any) -> Any:
    return x


def _unlink(path: Path) -> None:
    path.unlink(missing_ok=True)
