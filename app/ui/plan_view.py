"""Draw the latest plan: the predicted base and EE paths, and the sequencer's planned base path."""

from __future__ import annotations

import numpy as np
import viser

from app.runtime.snapshot import Snapshot


def _segments(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, np.float32)
    return np.stack([pts[:-1], pts[1:]], axis=1)


class PlanView:
    """Line segments under `/plan`: blue predicted base path, orange EE path, grey planned base path."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self._handles: dict[str, viser.LineSegmentsHandle] = {}
        self._last: dict[str, bytes] = {}

    def _lines(self, name: str, points: np.ndarray | None, color: tuple[int, int, int], width: float) -> None:
        if points is None or len(points) < 2:
            handle = self._handles.pop(name, None)
            if handle is not None:
                handle.remove()
            self._last.pop(name, None)
            return
        key = np.asarray(points, np.float32).round(3).tobytes()
        if self._last.get(name) == key:
            return
        self._last[name] = key
        self._handles[name] = self.server.scene.add_line_segments(f"/plan/{name}", _segments(points), colors=color,
                                                                  thickness=width)

    def update(self, snap: Snapshot) -> None:
        plan = snap.plan
        base = None if plan is None else np.column_stack([plan.base_path[:, :2], np.full(len(plan.base_path), 0.02)])
        self._lines("predicted_base", base, (40, 110, 240), 0.03)
        self._lines("predicted_ee", None if plan is None else plan.ee_path, (245, 140, 20), 0.02)
        path = snap.base_path
        planned = None if path is None else np.column_stack([path, np.full(len(path), 0.01)])
        self._lines("planned_base", planned, (120, 120, 120), 0.015)
