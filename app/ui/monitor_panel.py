"""Live monitoring: status line, solve time, task error per level, clearance and E[v] per object."""

from __future__ import annotations

import time
from collections import deque

import numpy as np
import viser
import viser.uplot as uplot

from app.snapshot import RunState, Snapshot

HISTORY = 300
MAX_OBJECTS = 6
PLOT_PERIOD_S = 0.5
"""Plots are re-sent at most twice a second: a software-rendered browser falls behind at 20 Hz."""
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def _finite(a: np.ndarray) -> np.ndarray:
    """NaN forward-filled (leading NaN → 0): one NaN makes viser's uPlot draw nothing at all."""
    a = np.asarray(a, float).copy()
    bad = ~np.isfinite(a)
    if bad.all():
        return np.zeros_like(a)
    idx = np.where(~bad, np.arange(len(a)), 0)
    np.maximum.accumulate(idx, out=idx)
    a = a[idx]
    a[: np.argmax(~bad)] = 0.0
    return a


def _series(labels: list[str]) -> tuple[uplot.Series, ...]:
    out = [uplot.Series(label="t (s)")]
    out += [uplot.Series(label=lab, stroke=_COLORS[i % len(_COLORS)], width=2) for i, lab in enumerate(labels)]
    return tuple(out)


class MonitorPanel:
    """A status line and four rolling plots (x axis: sim time, not wall time)."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.rows: deque[tuple] = deque(maxlen=HISTORY)
        self.solve = self.errors = self.clearance = self.consistency = None
        self._obj_ids: list[int] = []
        self._last_plot = 0.0
        self.status = server.gui.add_markdown("**starting**", order=0)
        self.progress = server.gui.add_markdown("", order=1)

    def build_plots(self) -> None:
        """The plots, in whatever GUI container is active (the studio's 'Monitor' tab)."""
        server = self.server
        scales = {"x": uplot.Scale(time=False, auto=True)}
        empty = (np.zeros(1), np.zeros(1), np.zeros(1))
        self.solve = server.gui.add_uplot(empty, _series(["solve ms", "map ms"]), title="Solve / mapping time (ms)",
                                          scales=scales, aspect=2.0)
        self.errors = server.gui.add_uplot(empty, _series(["level 1", "level 2"]), title="Task error per level",
                                           scales=scales, aspect=2.0)
        self.clearance = server.gui.add_uplot((np.zeros(1), np.zeros(1)), _series(["min distance (m)"]),
                                              title="Robot–box distance (m)", scales=scales, aspect=2.0)
        obj_empty = tuple(np.zeros(1) for _ in range(MAX_OBJECTS + 1))
        self.consistency = server.gui.add_uplot(obj_empty, _series([f"obj {i}" for i in range(MAX_OBJECTS)]),
                                                title="E[v] per object", scales=scales, aspect=2.0)

    def update(self, snap: Snapshot) -> None:
        self.status.content = self._status(snap)
        self.progress.content = self._progress(snap)
        plan = snap.plan
        errs = list(plan.task_errors) if plan is not None else []
        objects = [o for o in (snap.object_map.objects if snap.object_map else ())][:MAX_OBJECTS]
        ev = {o.id: o.consistency for o in objects}
        for o in objects:
            if o.id not in self._obj_ids and len(self._obj_ids) < MAX_OBJECTS:
                self._obj_ids.append(o.id)
        self.rows.append((snap.state.t, snap.timings_ms.get("solve", np.nan), snap.timings_ms.get("mapping", np.nan),
                          errs[0] if errs else np.nan, errs[1] if len(errs) > 1 else np.nan, snap.min_distance_m,
                          [ev.get(i, np.nan) for i in self._obj_ids] + [np.nan] * (MAX_OBJECTS - len(self._obj_ids))))
        now = time.monotonic()
        if self.solve is None or now - self._last_plot < PLOT_PERIOD_S:
            return
        self._last_plot = now
        cols = list(zip(*self.rows, strict=True))
        t = np.asarray(cols[0], float)
        self.solve.data = (t, _finite(cols[1]), _finite(cols[2]))
        self.errors.data = (t, _finite(cols[3]), _finite(cols[4]))
        self.clearance.data = (t, _finite(cols[5]))
        evs = np.asarray(cols[6], float)
        self.consistency.data = (t, *[_finite(evs[:, i]) for i in range(MAX_OBJECTS)])

    @staticmethod
    def _status(snap: Snapshot) -> str:
        icon = {RunState.RUNNING: "▶", RunState.PAUSED: "⏸", RunState.ESTOP: "⛔", RunState.FINISHED: "✔",
                RunState.FAILED: "✖", RunState.FAULT: "⚠"}.get(snap.run_state, "■")
        return (f"{icon} **{snap.run_state.value}** · t = {snap.state.t:.1f} s · {snap.status}  \n"
                f"map: {snap.map_kind} · constraint: {snap.constraint} · clearance {snap.min_distance_m:.2f} m · "
                f"collisions {snap.collisions}")

    @staticmethod
    def _progress(snap: Snapshot) -> str:
        lines = []
        for p in snap.progress:
            mark = {"done": "✔", "failed": "✖", "active": "▶"}.get(p.outcome.value, "·")
            extra = f" — {p.message}" if p.message else ""
            lines.append(f"{mark} {p.index + 1}. {p.name}{extra}")
        return "  \n".join(lines) or "_no subtasks_"
