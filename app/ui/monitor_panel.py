"""Live monitoring plots: solve and mapping time, task error per level, clearance and E[v] per object, and with
localization its health (position and heading error against the truth in simulation, corrections per second,
rejected and degenerate registrations so far), over the whole run: the last `WINDOW` rows at full rate, the
older ones thinned to at most `OLDER_MAX` (every other one dropped each time they reach it), so a run stays in
the monitor after it ends."""

from __future__ import annotations

import time
from collections import deque

import numpy as np
import viser
import viser.uplot as uplot

from app.object_label import object_label, operator_names
from app.runtime.snapshot import RunState, Snapshot
from core.angles import wrap_angle

WINDOW = 300
"""Rows (snapshots) kept at full rate: the last 15 s at the studio's 20 snapshots a second."""
OLDER_MAX = 600
"""Older rows are thinned to at most this many."""
MAX_OBJECTS = 6
PLOT_PERIOD_S = 0.5
"""Plots are re-sent at most twice a second: a software-rendered browser falls behind at 20 Hz."""
_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def _finite(a: np.typing.ArrayLike) -> np.ndarray:
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


LEGEND = uplot.Legend(live=False)
"""The legend names the series; uPlot's live legend shows each value under the cursor, '--' until hovered."""


def _series(labels: list[str]) -> tuple[uplot.Series, ...]:
    out = [uplot.Series(label="t (s)")]
    out += [uplot.Series(label=lab, stroke=_COLORS[i % len(_COLORS)], width=2) for i, lab in enumerate(labels)]
    return tuple(out)


def _axes(y_label: str) -> tuple[uplot.Axis, uplot.Axis]:
    """Sim time below, `y_label` (with its unit) on the left, wide enough that neither label is clipped."""
    return (uplot.Axis(label="sim time (s)", size=44, labelSize=22),
            uplot.Axis(label=y_label, size=76, labelSize=26, labelGap=2))


class RunHistory:
    """The rows of one run: the newest `window` at full rate, older ones thinned (to ≤ `older_max`)."""

    def __init__(self, window: int = WINDOW, older_max: int = OLDER_MAX) -> None:
        self.recent: deque[tuple] = deque(maxlen=window)
        self.older: list[tuple] = []
        self.older_max = older_max

    def append(self, row: tuple) -> None:
        if len(self.recent) == self.recent.maxlen:
            self.older.append(self.recent[0])
            if len(self.older) > self.older_max:
                self.older = self.older[::2]
        self.recent.append(row)

    def clear(self) -> None:
        self.recent.clear()
        self.older.clear()

    def rows(self) -> list[tuple]:
        return [*self.older, *self.recent]

    def __len__(self) -> int:
        return len(self.older) + len(self.recent)

    def __getitem__(self, k: int) -> tuple:
        return self.rows()[k]


class MonitorPanel:
    """Four rolling plots (x axis: sim time, not wall time)."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.rows = RunHistory()
        self._last_t = -np.inf
        self._last_state: RunState | None = None
        self.solve: viser.GuiUplotHandle | None = None
        self.errors: viser.GuiUplotHandle | None = None
        self.clearance: viser.GuiUplotHandle | None = None
        self.consistency: viser.GuiUplotHandle | None = None
        self.pose_error: viser.GuiUplotHandle | None = None
        self.corrections: viser.GuiUplotHandle | None = None
        """Localization's plots: shown once a snapshot carries `localization` (a run without it shows none)."""
        self._obj_ids: list[int] = []
        self._names: dict[int, str] = {}
        """The operator's names by map id ('#4 shelf' in the legend)."""
        self._legend: tuple[str, ...] = ()
        self._last_plot = 0.0

    def build_plots(self) -> None:
        """The plots, in whatever GUI container is active (the studio's 'Monitor' tab)."""
        server = self.server
        scales = {"x": uplot.Scale(time=False, auto=True)}
        empty = (np.zeros(1), np.zeros(1), np.zeros(1))
        self.solve = server.gui.add_uplot(empty, _series(["solve ms", "map ms"]), title="Solve / mapping time (ms)",
                                          scales=scales, aspect=2.0, legend=LEGEND, axes=_axes("time (ms)"))
        self.errors = server.gui.add_uplot(empty, _series(["level 1", "level 2"]),
                                           title="Task error per level, ‖e‖ at the first node (m, rad)",
                                           scales=scales, aspect=2.0, legend=LEGEND, axes=_axes("‖e‖ (m, rad)"))
        self.clearance = server.gui.add_uplot((np.zeros(1), np.zeros(1)), _series(["min distance (m)"]),
                                              title="Robot–box distance (m)", scales=scales, aspect=2.0, legend=LEGEND,
                                              axes=_axes("distance (m)"))
        obj_empty = tuple(np.zeros(1) for _ in range(MAX_OBJECTS + 1))
        self.consistency = server.gui.add_uplot(obj_empty, _series(self.object_labels()),
                                                title="E[v] per object (map id)", scales=scales, aspect=2.0,
                                                legend=LEGEND, axes=_axes("E[v] (probability)"))
        self._legend = tuple(self.object_labels())
        self.pose_error = server.gui.add_uplot(
            empty, _series(["position error (m)", "heading error (deg)"]),
            title="Pose error against the truth (simulation)", scales=scales, aspect=2.0, legend=LEGEND,
            axes=_axes("error (m, deg)"))
        self.corrections = server.gui.add_uplot(
            (np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1)),
            _series(["accepted per s", "rejected (count)", "degenerate (count)"]),
            title="Localization: corrections per second, rejected and degenerate registrations", scales=scales,
            aspect=2.0, legend=LEGEND, axes=_axes("rate (1/s), count"))
        self.pose_error.visible = self.corrections.visible = False

    def object_labels(self) -> list[str]:
        """The E[v] plot's series names: each object's map label ('#4', '#4 shelf' once named), '—' for a series
        not used yet."""
        return [object_label(i, self._names.get(i)) for i in self._obj_ids] + ["—"] * (MAX_OBJECTS - len(self._obj_ids))

    def load_history(self, snapshots: list[Snapshot]) -> None:
        """Start the plots over from these snapshots (a replay jumped in time); the next update draws them."""
        self.rows.clear()
        self._obj_ids.clear()
        for snap in snapshots:
            self._add_row(snap)
        if snapshots:  # what follows continues this history
            self._last_state, self._last_t = snapshots[-1].run_state, snapshots[-1].state.t
        self._last_plot = 0.0

    def _new_run(self, snap: Snapshot) -> bool:
        """A run began (Start from rest) or time went back (Reset): the history starts over."""
        began = snap.run_state == RunState.RUNNING and self._last_state not in (RunState.RUNNING, RunState.PAUSED,
                                                                                   None)
        back = snap.state.t < self._last_t - 1e-9
        self._last_state, self._last_t = snap.run_state, snap.state.t
        return began or back

    def update(self, snap: Snapshot) -> None:
        if self._new_run(snap):
            self.rows.clear()
            self._obj_ids.clear()
        self._add_row(snap)
        now = time.monotonic()
        if self.solve is None or now - self._last_plot < PLOT_PERIOD_S:
            return
        self._last_plot = now
        self._plot()

    def _add_row(self, snap: Snapshot) -> None:
        plan = snap.plan
        errs = list(plan.task_errors) if plan is not None else []
        objects = [o for o in (snap.object_map.objects if snap.object_map else ())][:MAX_OBJECTS]
        ev = {o.id: o.consistency for o in objects}
        self._names.update(operator_names(snap.anchors))
        for o in objects:
            if o.id not in self._obj_ids and len(self._obj_ids) < MAX_OBJECTS:
                self._obj_ids.append(o.id)
        self.rows.append((snap.state.t, snap.timings_ms.get("solve", np.nan), snap.timings_ms.get("mapping", np.nan),
                          errs[0] if errs else np.nan, errs[1] if len(errs) > 1 else np.nan, snap.min_distance_m,
                          [ev.get(i, np.nan) for i in self._obj_ids] + [np.nan] * (MAX_OBJECTS - len(self._obj_ids)),
                          localization_row(snap)))

    def _plot(self) -> None:
        if self.solve is None or self.errors is None or self.clearance is None or self.consistency is None or \
                not self.rows:
            return
        cols = list(zip(*self.rows.rows(), strict=True))
        t = np.asarray(cols[0], float)
        self.solve.data = (t, _finite(cols[1]), _finite(cols[2]))
        self.errors.data = (t, _finite(cols[3]), _finite(cols[4]))
        self.clearance.data = (t, _finite(cols[5]))
        evs = np.asarray(cols[6], float)
        self.consistency.data = (t, *[_finite(evs[:, i]) for i in range(MAX_OBJECTS)])
        legend = tuple(self.object_labels())
        if legend != self._legend:
            self._legend = legend
            self.consistency.series = _series(list(legend))
        loc = np.asarray(cols[7], float)
        shown = not np.all(np.isnan(loc))  # localization in this run
        if self.pose_error is None or self.corrections is None:
            return
        if self.pose_error.visible != shown:
            self.pose_error.visible = self.corrections.visible = shown
        if not shown:
            return
        self.pose_error.data = (t, _finite(loc[:, 0]), _finite(loc[:, 1]))
        self.corrections.data = (t, _finite(loc[:, 2]), _finite(loc[:, 3]), _finite(loc[:, 4]))


def localization_row(snap: Snapshot) -> tuple[float, float, float, float, float]:
    """(position error m, heading error deg, corrections accepted per s, rejected, degenerate so far); the errors
    against the truth in simulation only (NaN otherwise), all NaN without localization."""
    health = snap.localization
    if health is None:
        return np.nan, np.nan, np.nan, np.nan, np.nan
    position = heading = np.nan
    if snap.base_estimate is not None and snap.base_true is not None:
        d = snap.base_estimate - snap.base_true
        position = float(np.hypot(d[0], d[1]))
        heading = float(np.degrees(abs(wrap_angle(d[2]))))
    return position, heading, health.accepted_per_s, float(health.rejected), float(health.degenerate)
