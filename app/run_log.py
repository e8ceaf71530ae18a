"""What a run leaves behind: one row per control period, summaries, and the report files."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.atomic_file import write_text_atomic
from core.types import Plan, RobotState


@dataclass
class RunLog:
    """Rows recorded at the control rate by the runtime."""

    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    v: list[np.ndarray] = field(default_factory=list)
    qdot: list[np.ndarray] = field(default_factory=list)
    task_errors: list[tuple[float, ...]] = field(default_factory=list)
    solve_ms: list[float] = field(default_factory=list)
    plan_status: list[str] = field(default_factory=list)
    min_distance_m: list[float] = field(default_factory=list)
    collisions: list[int] = field(default_factory=list)
    run_state: list[str] = field(default_factory=list)
    subtask: list[int] = field(default_factory=list)
    timings_ms: list[dict[str, float]] = field(default_factory=list)

    def record(self, state: RobotState, plan: Plan | None, min_distance_m: float, collisions: int, run_state,
               subtask: int, qdot: np.ndarray, timings_ms: dict[str, float]) -> None:
        self.t.append(float(state.t))
        self.q.append(state.q.copy())
        self.v.append(state.v.copy())
        self.qdot.append(np.asarray(qdot, float).copy())
        self.task_errors.append(tuple(plan.task_errors) if plan is not None else ())
        self.solve_ms.append(float(sum(plan.solve_ms)) if plan is not None else math.nan)
        self.plan_status.append(plan.status.value if plan is not None else "none")
        self.min_distance_m.append(float(min_distance_m))
        self.collisions.append(int(collisions))
        self.run_state.append(str(run_state))
        self.subtask.append(int(subtask))
        self.timings_ms.append(dict(timings_ms))

    def base_path_length_m(self) -> float:
        if len(self.q) < 2:
            return 0.0
        xy = np.array([q[:2] for q in self.q])
        return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())

    def summary(self) -> dict[str, float]:
        """Figures of the run: duration, path length, clearance, collisions, solve times, speeds."""
        solve = np.array([s for s in self.solve_ms if not math.isnan(s)])
        dist = np.array([d for d in self.min_distance_m if not math.isnan(d)])
        speed = np.array([np.hypot(*v[:2]) for v in self.v]) if self.v else np.zeros(1)
        return {
            "duration_s": (self.t[-1] - self.t[0]) if self.t else 0.0,
            "base_path_length_m": self.base_path_length_m(),
            "min_clearance_m": float(dist.min()) if len(dist) else math.nan,
            "collisions": float(self.collisions[-1]) if self.collisions else 0.0,
            "solve_ms_median": float(np.median(solve)) if len(solve) else math.nan,
            "solve_ms_p99": float(np.percentile(solve, 99)) if len(solve) else math.nan,
            "max_base_speed_mps": float(speed.max()),
            "mean_base_speed_mps": float(speed.mean()),
            "fallback_steps": float(sum(s not in ("ok", "ok_with_slack", "none") for s in self.plan_status)),
        }

    def to_json(self) -> dict:
        return {
            "summary": self.summary(),
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
