"""Where the run stands: status line, a progress bar, time left, the subtasks with their outcomes, and a
notice when the planner moved a base goal off a box ("goal moved 0.11 m to clear box_b")."""

from __future__ import annotations

from collections import deque

import numpy as np
import viser

from app.runtime.snapshot import RunState, Snapshot
from app.target_check import obstacle_name
from app.ui import glyphs
from app.ui.colors import NamedColour
from app.ui.notify import notify_all
from tasks.sequencer import GoalShift, SubtaskProgress, plural

ETA_WINDOW_S = 3.0
"""The time left of the active subtask is its remaining error over the rate it fell in this window."""


def duration(seconds: float) -> str:
    """'0.4 s', '45 s', '2 min 05 s' (tenths below 10 s: a short subtask never reads '0 s')."""
    seconds = max(0.0, float(seconds))
    if seconds < 10:
        return f"{seconds:.1f} s"
    return f"{seconds:.0f} s" if seconds < 60 else f"{int(seconds // 60)} min {int(seconds % 60):02d} s"


def fresh(snap: Snapshot) -> bool:
    """A sequence not run yet (all pending): after a finished or failed run, the one authored since."""
    return bool(snap.progress) and all(p.outcome.value == "pending" for p in snap.progress)


def shown_state(snap: Snapshot) -> str:
    """The run state as the operator should read it: 'ready' once a new sequence replaced a finished one."""
    if snap.run_state in (RunState.FINISHED, RunState.FAILED, RunState.IDLE) and fresh(snap):
        return "ready"
    return snap.run_state.value


def under_way_in(snap: Snapshot) -> bool:
    """A run under way: running, or paused/stopped mid-sequence (Start resumes it; edits wait for the next run)."""
    if snap.run_state == RunState.RUNNING:
        return True
    return snap.run_state not in (RunState.FINISHED, RunState.FAILED) and not fresh(snap) and bool(snap.progress) \
        and not all(p.outcome.value in ("done", "skipped") for p in snap.progress)


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
        self._run_version: int | None = None
        """The authored sequence's version when the run under way began (edits after it run in the next run)."""
        self._was_under_way = False

    def update(self, snap: Snapshot) -> None:
        under_way = under_way_in(snap)
        if under_way and not self._was_under_way:
            self._run_version = snap.sequence_version
        self._was_under_way = under_way
        self.status.content = self._status(snap)
        self.bar.value = round(100.0 * self._fraction(snap), 1)
        self.bar.color = BAR_COLOURS.get(snap.run_state, "blue")
        self.time_left.content = self._time_left(snap)
        self.subtasks.content = self._list(snap)
        self._announce_goal_shifts(snap)

    @staticmethod
    def _status(snap: Snapshot) -> str:
        state = shown_state(snap)
        icon = glyphs.RUN_STATE.get(RunState.IDLE if state == "ready" else snap.run_state, glyphs.OTHER_STATE)
        return (f"{icon} **{state}** · t = {snap.state.t:.1f} s · {snap.status}  \n"
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
        text = self._progress_text(snap)
        if under_way_in(snap) and self._run_version is not None and snap.sequence_version != self._run_version:
            text += (f"  \n{glyphs.WARNING} the sequence was edited during the run: the edits run in the next run "
                     "(Start after this one ends, or Reset)")
        return text

    def _progress_text(self, snap: Snapshot) -> str:
        progress = snap.progress
        if not progress:
            return ""
        pending = [p for p in progress if p.outcome.value == "pending"]
        budget = sum(p.timeout_s for p in pending if np.isfinite(p.timeout_s))
        by_timeouts = f"at most {duration(budget)} by their timeouts" if budget > 0 else ""
        if fresh(snap):
            return f"{plural(len(progress), 'subtask')}" + (f", {by_timeouts}" if by_timeouts else "")
        ran = duration(sum(p.elapsed_s for p in progress))
        if snap.run_state == RunState.FINISHED:
            return f"finished after {ran}"
        active = self._active(snap)
        if active is None:
            failed = [p for p in progress if p.outcome.value == "failed"]
            stopped = (failed + pending)[0] if failed or pending else None
            where = f" at subtask {stopped.index + 1}/{len(progress)}" if stopped is not None else ""
            return f"stopped{where} after {ran}" + (f"; {len(pending)} not run" if pending else "")
        return self._active_text(snap, active, pending, by_timeouts)

    def _active_text(self, snap: Snapshot, active: SubtaskProgress, pending: list[SubtaskProgress],
                     by_timeouts: str) -> str:
        """'subtask 2/5: about 12 s left (1.20 m to go) · times out in 38 s · then 3 more (at most 2 min)'; the
        estimate never exceeds the time to the timeout (it says when the rate would not make it)."""
        eta = self._eta(active, snap.state.t)
        timeout_left = active.timeout_s - active.elapsed_s if np.isfinite(active.timeout_s) else np.inf
        if active.no_path:
            left = "no path to the goal"
        elif eta is None:
            left = "time left unknown yet"
        elif eta > timeout_left:
            left = "too slow to make it before the timeout at this rate"
        else:
            left = f"about {duration(eta)} left"
        timeout = f" · times out in {duration(timeout_left)}" if np.isfinite(timeout_left) else ""
        after = f" · then {len(pending)} more" + (f" ({by_timeouts})" if by_timeouts else "") if pending else ""
        return (f"subtask {active.index + 1}/{len(snap.progress)}: {left} ({active.position_error_m:.2f} m to go)"
                f"{timeout}{after}")

    def _shift_text(self, shift: GoalShift, snap: Snapshot) -> str:
        box = obstacle_name(np.array(shift.original), snap)
        return f"goal moved {shift.distance_m:.2f} m to clear {box or 'an obstacle'}"

    def _message(self, p: SubtaskProgress, snap: Snapshot) -> str:
        """The subtask's message, with the obstacles it speaks of named as the map names them."""
        if p.goal_shift is not None:
            return self._shift_text(p.goal_shift, snap)
        if p.blocked is not None and p.blocked.obstacle_xy is not None and p.outcome.value == "active":
            name = obstacle_name(np.array(p.blocked.obstacle_xy), snap) or "an obstacle"
            return (f"blocked: no progress for {duration(p.blocked.for_s)}, {p.position_error_m:.2f} m from the "
                    f"goal; nearest obstacle {name}, {p.blocked.obstacle_m:.2f} m away (Skip or Stop)")
        return p.message

    def _list(self, snap: Snapshot) -> str:
        lines = []
        for p in snap.progress:
            mark = glyphs.OUTCOME.get(p.outcome.value, "·")
            message = self._message(p, snap)
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
