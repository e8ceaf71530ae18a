"""Where the run stands: status line, a progress bar, time left, the subtasks with their outcomes, and a
notice when the planner moved a base goal off a box ("goal moved 0.11 m to clear box_b")."""

from __future__ import annotations

from collections import deque

import numpy as np
import viser

from app.runtime.snapshot import RunState, Snapshot
from app.target_check import nearest_obstacle, snapshot_obstacles
from app.ui import glyphs
from app.ui.colors import NamedColour
from app.ui.notify import notify_all
from tasks.sequencer import GoalShift, SubtaskProgress

ETA_WINDOW_S = 3.0
"""The time left of the active subtask is its remaining error over the rate it fell in this window."""


def duration(seconds: float) -> str:
    """'45 s', '2 min 05 s'."""
    seconds = max(0.0, float(seconds))
    return f"{seconds:.0f} s" if seconds < 60 else f"{int(seconds // 60)} min {int(seconds % 60):02d} s"


BAR_COLOURS: dict[RunState, NamedColour] = {RunState.FAILED: "red", RunState.ESTOP: "red", RunState.FINISHED: "green"}
"""The progress bar's colour by run state (blue otherwise)."""

class ProgressPanel:
    """Markdown and a progress bar at the top of the sidebar (always visible)."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.status = server.gui.add_markdown("**starting**", order=0)
        self.bar = server.gui.add_progress_bar(0.0, order=1)
        self.time_left = server.gui.add_markdown("", order=2)
        self.subtasks = server.gui.add_markdown("", order=4)
        self._first_error: dict[int, float] = {}
        self._recent: deque[tuple[float, float]] = deque()
        self._recent_index = -1
        self._announced: set[tuple] = set()

    def update(self, snap: Snapshot) -> None:
        self.status.content = self._status(snap)
        self.bar.value = round(100.0 * self._fraction(snap), 1)
        self.bar.color = BAR_COLOURS.get(snap.run_state, "blue")
        self.time_left.content = self._time_left(snap)
        self.subtasks.content = self._list(snap)
        self._announce_goal_shifts(snap)

    @staticmethod
    def _status(snap: Snapshot) -> str:
        icon = glyphs.RUN_STATE.get(snap.run_state, glyphs.OTHER_STATE)
        return (f"{icon} **{snap.run_state.value}** · t = {snap.state.t:.1f} s · {snap.status}  \n"
                f"map: {snap.map_kind} · constraint: {snap.constraint} · clearance {snap.min_distance_m:.2f} m · "
                f"collisions {snap.collisions}")

    def _active(self, snap: Snapshot) -> SubtaskProgress | None:
        return next((p for p in snap.progress if p.outcome.value == "active"), None)

    def _fraction(self, snap: Snapshot) -> float:
        """Done subtasks plus the part of the active one its error has shrunk by since it began."""
        if not snap.progress:
            return 0.0
        done = sum(p.outcome.value == "done" for p in snap.progress)
        active = self._active(snap)
        part = 0.0
        if active is not None and np.isfinite(active.position_error_m):
            first = self._first_error.setdefault(active.index, max(active.position_error_m, 1e-6))
            part = float(np.clip(1.0 - active.position_error_m / first, 0.0, 1.0))
        if snap.run_state == RunState.IDLE and not done:
            self._first_error.clear()
        return (done + part) / len(snap.progress)

    def _eta(self, active: SubtaskProgress, t: float) -> float | None:
        """Seconds until the active subtask's error reaches its tolerance at the rate it fell lately."""
        if active.index != self._recent_index:
            self._recent.clear()
            self._recent_index = active.index
        self._recent.append((t, active.position_error_m))
        while self._recent and self._recent[0][0] < t - ETA_WINDOW_S:
            self._recent.popleft()
        (t0, e0), (t1, e1) = self._recent[0], self._recent[-1]
        if t1 - t0 < 0.5 or not np.isfinite(e0 - e1) or e0 - e1 <= 1e-3:
            return None
        return max(0.0, e1) / ((e0 - e1) / (t1 - t0))

    def _time_left(self, snap: Snapshot) -> str:
        progress = snap.progress
        if not progress:
            return ""
        pending = [p for p in progress if p.outcome.value == "pending"]
        budget = sum(p.timeout_s for p in pending if np.isfinite(p.timeout_s))
        if snap.run_state == RunState.FINISHED:
            return f"finished after {duration(sum(p.elapsed_s for p in progress))}"
        active = self._active(snap)
        if active is None:
            return f"{len(progress)} subtasks, at most {duration(budget)} by their timeouts"
        eta = self._eta(active, snap.state.t)
        left = "time left unknown yet" if eta is None else f"about {duration(eta)} left"
        timeout = ""
        if np.isfinite(active.timeout_s):
            timeout = f" · times out in {duration(active.timeout_s - active.elapsed_s)}"
        after = f" · then {len(pending)} more (at most {duration(budget)})" if pending else ""
        return (f"subtask {active.index + 1}/{len(progress)}: {left} ({active.position_error_m:.2f} m to go)"
                f"{timeout}{after}")

    def _shift_text(self, shift: GoalShift, snap: Snapshot) -> str:
        box = nearest_obstacle(np.array(shift.original), snapshot_obstacles(snap))
        return f"goal moved {shift.distance_m:.2f} m to clear {box or 'an obstacle'}"

    def _list(self, snap: Snapshot) -> str:
        lines = []
        for p in snap.progress:
            mark = glyphs.OUTCOME.get(p.outcome.value, "·")
            message = self._shift_text(p.goal_shift, snap) if p.goal_shift is not None else p.message
            lines.append(f"{mark} {p.index + 1}. {p.name}" + (f" — {message}" if message else ""))
        return "  \n".join(lines) or "_no subtasks_"

    def _announce_goal_shifts(self, snap: Snapshot) -> None:
        for p in snap.progress:
            if p.goal_shift is None or p.outcome.value != "active":
                continue
            key = (snap.sequence_version, p.index, tuple(np.round(p.goal_shift.driven, 2)))
            if key not in self._announced:
                self._announced.add(key)
                notify_all(self.server, f"Subtask {p.index + 1}: goal moved", self._shift_text(p.goal_shift, snap),
                           color="yellow")
