"""What went wrong during a run, counted by kind: the studio's problems panel and the run report read it.

The runtime records (`record(kind, t, message)`) from a few hook points: every controller step
(`observe_plan`: QP failures, fallback plans, slow solves), a crashed loop (fault), the bridge's stale
state, a live loop that missed its period (watchdog), unknown space slowing the base (one per episode,
`app/runtime/unknown_ahead.py`), a camera rate the live mapping cannot keep (each frame it skipped), a pose estimate
the loop does not trust (one per episode, `core/localization/health.py`). Each kind
keeps its count, first and last time and last message; the log is thread-safe (the loops and the bridge record
from their own threads).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from enum import StrEnum

from core.types import Plan, PlanReason, PlanStatus


class ProblemKind(StrEnum):
    QP_FAILURE = "qp_failure"
    FALLBACK = "fallback"
    SLOW_SOLVE = "slow_solve"
    FAULT = "fault"
    STALE_STATE = "stale_state"
    WATCHDOG = "watchdog"
    UNKNOWN_SPACE = "unknown_space"
    ANCHORED_TARGET = "anchored_target"
    FRAMES_SKIPPED = "frames_skipped"
    LOCALIZATION = "localization"

    @property
    def label(self) -> str:
        return _LABELS[self]

    def counted(self, n: int) -> str:
        """'1 slow solve', '2 slow solves'."""
        return f"{n} {_SINGULAR[self] if n == 1 else _LABELS[self]}"


_LABELS = {ProblemKind.QP_FAILURE: "QP failures", ProblemKind.FALLBACK: "fallback plans",
           ProblemKind.SLOW_SOLVE: "slow solves", ProblemKind.FAULT: "faults", ProblemKind.STALE_STATE: "stale state",
           ProblemKind.WATCHDOG: "watchdog events", ProblemKind.UNKNOWN_SPACE: "unknown space ahead",
           ProblemKind.ANCHORED_TARGET: "anchored targets out of reach",
           ProblemKind.FRAMES_SKIPPED: "depth frames skipped",
           ProblemKind.LOCALIZATION: "untrusted localization episodes"}
_SINGULAR = {ProblemKind.QP_FAILURE: "QP failure", ProblemKind.FALLBACK: "fallback plan",
             ProblemKind.SLOW_SOLVE: "slow solve", ProblemKind.FAULT: "fault", ProblemKind.STALE_STATE: "stale state",
             ProblemKind.WATCHDOG: "watchdog event",
             ProblemKind.UNKNOWN_SPACE: "unknown space ahead",
             ProblemKind.ANCHORED_TARGET: "anchored target out of reach",
             ProblemKind.FRAMES_SKIPPED: "depth frame skipped",
             ProblemKind.LOCALIZATION: "untrusted localization episode"}

@dataclass(frozen=True)
class ProblemCount:
    """How often one kind of problem happened: count, first and last sim time (s), the last message."""

    kind: ProblemKind
    count: int
    first_t: float
    last_t: float
    last_message: str


class ProblemLog:
    """Counts of problems by kind; `slow_solve_ms` is the solve time from which a step counts as slow."""

    def __init__(self, slow_solve_ms: float = 100.0) -> None:
        self.slow_solve_ms = slow_solve_ms
        self._lock = threading.Lock()
        self._counts: dict[ProblemKind, ProblemCount] = {}

    def record(self, kind: ProblemKind, t: float, message: str) -> None:
        """Count one problem of `kind` at sim time t (s)."""
        kind = ProblemKind(kind)
        with self._lock:
            old = self._counts.get(kind)
            first = t if old is None else old.first_t
            self._counts[kind] = ProblemCount(kind, 1 if old is None else old.count + 1, first, t, message)

    def observe_plan(self, plan: Plan, t: float, solve_ms: float | None = None) -> None:
        """Count what one controller step shows, by the plan's `reason` (never by parsing its message): a failed
        QP (even when an earlier level's plan was kept), a fallback (braking) plan, a solve slower than
        `slow_solve_ms` (one the controller discarded as too slow has the reason SOLVE_TIMEOUT)."""
        message = plan.message or plan.status.value
        if plan.reason == PlanReason.QP_FAILED:
            self.record(ProblemKind.QP_FAILURE, t, message)
        if plan.status in (PlanStatus.FALLBACK, PlanStatus.STOPPING, PlanStatus.FAILED) and \
                plan.reason != PlanReason.NO_TASK:  # holding with nothing to do is no problem
            self.record(ProblemKind.FALLBACK, t, message)
        if plan.reason == PlanReason.SOLVE_TIMEOUT:
            self.record(ProblemKind.SLOW_SOLVE, t, message)
        elif solve_ms is not None and solve_ms > self.slow_solve_ms:
            digits = 0 if round(solve_ms) > round(self.slow_solve_ms) else 1  # never "100 ms (> 100 ms)"
            self.record(ProblemKind.SLOW_SOLVE, t,
                        f"solve took {solve_ms:.{digits}f} ms (> {self.slow_solve_ms:.0f} ms)")

    def counts(self) -> tuple[ProblemCount, ...]:
        """Every kind seen so far, in the order of `ProblemKind`."""
        with self._lock:
            return tuple(self._counts[k] for k in ProblemKind if k in self._counts)

    def count(self, kind: ProblemKind) -> int:
        with self._lock:
            c = self._counts.get(ProblemKind(kind))
            return 0 if c is None else c.count

    @property
    def total(self) -> int:
        return sum(c.count for c in self.counts())

    def to_json(self) -> dict[str, dict]:
        """{kind: {count, first_t, last_t, last_message}} for the run report: every kind, unseen ones with count 0
        (first_t, last_t None, last_message "")."""
        seen = {c.kind: c for c in self.counts()}
        return {k.value: {"count": 0, "first_t": None, "last_t": None, "last_message": ""} if k not in seen else
                {"count": seen[k].count, "first_t": seen[k].first_t, "last_t": seen[k].last_t,
                 "last_message": seen[k].last_message} for k in ProblemKind}


def summary_line(counts: tuple[ProblemCount, ...]) -> str:
    """'2 QP failures (last at 12.3 s), 1 slow solve (...)', or 'no problems'."""
    if not counts:
        return "no problems"
    return ", ".join(f"{c.kind.counted(c.count)} (last at {c.last_t:.1f} s)" for c in counts)
