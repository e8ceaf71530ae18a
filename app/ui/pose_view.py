"""Draw the pose estimate's health in the 3D view (with localization only): the estimated base pose's 3σ
ellipse in x-y and its ±3σ heading wedge, and in simulation the true base pose as a translucent ghost (the
base's footprint) with its heading. Read from the snapshot's `base_estimate`, `localization.covariance` and
`base_true`."""

from __future__ import annotations

import math

import numpy as np
import viser

from app.runtime.snapshot import Snapshot

SIGMAS = 3.0
"""The ellipse and the wedge are drawn at this many standard deviations."""
ELLIPSE_POINTS = 48
WEDGE_LENGTH_M = 0.9
Z_M = 0.03
"""The ghost's outline lies just above the floor; the ellipse and wedge just above the base's top (`base_size_m`),
where the body does not hide them."""
ESTIMATE_COLOR = (220, 40, 160)
UNTRUSTED_COLOR = (230, 30, 30)
GHOST_COLOR = (40, 200, 120)


def ellipse(centre_xy: np.ndarray, P_xy: np.ndarray, sigmas: float = SIGMAS, n: int = ELLIPSE_POINTS) -> np.ndarray:
    """Points (n+1, 2) of the `sigmas`-σ ellipse of the 2×2 covariance P_xy around centre_xy (closed)."""
    values, vectors = np.linalg.eigh(0.5 * (P_xy + P_xy.T))
    radii = sigmas * np.sqrt(np.maximum(values, 0.0))
    a = np.linspace(0.0, 2 * math.pi, n + 1)
    circle = np.stack([np.cos(a), np.sin(a)], axis=1) * radii
    return np.asarray(centre_xy, float) + circle @ vectors.T


def wedge(pose: np.ndarray, sigma_yaw: float, length: float = WEDGE_LENGTH_M, sigmas: float = SIGMAS,
          n: int = 12) -> np.ndarray:
    """Polyline (n+3, 2) of the heading wedge: base centre → the arc yaw ± sigmas σ_yaw at `length` → centre."""
    half = min(sigmas * sigma_yaw, math.pi)
    a = pose[2] + np.linspace(-half, half, n + 1)
    arc = np.asarray(pose[:2], float) + length * np.stack([np.cos(a), np.sin(a)], axis=1)
    return np.vstack([pose[:2], arc, pose[:2]])


def footprint(pose: np.ndarray, length: float, width: float) -> np.ndarray:
    """The base's rectangle (5, 2, closed) and a heading tick at `pose`."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    corners = np.array([[length, width], [-length, width], [-length, -width], [length, -width], [length, width]]) / 2
    return np.asarray(pose[:2], float) + corners @ np.array([[c, s], [-s, c]])


def _segments(xy: np.ndarray, z: float) -> np.ndarray:
    pts = np.column_stack([xy, np.full(len(xy), z)]).astype(np.float32)
    return np.stack([pts[:-1], pts[1:]], axis=1)


class PoseView:
    """Nodes under `/localization`: `ellipse`, `wedge` (the estimate), `ghost` and `ghost_outline` (the truth)."""

    def __init__(self, server: viser.ViserServer, base_size_m: tuple[float, float, float]) -> None:
        self.server = server
        self.base_size_m = base_size_m
        self.handles: dict[str, viser.SceneNodeHandle] = {}
        self._ghost: viser.BoxHandle | None = None
        self._last: dict[str, bytes | None] = {}

    def _lines(self, name: str, xy: np.ndarray | None, color: tuple[int, int, int], width: float,
               z: float = Z_M) -> None:
        key = None if xy is None else np.asarray(xy, np.float32).round(3).tobytes() + bytes(color)
        if key == self._last.get(name):
            return  # unchanged: nothing re-sent
        self._last[name] = key
        old = self.handles.pop(name, None)
        if old is not None:
            old.remove()
        if xy is not None:
            self.handles[name] = self.server.scene.add_line_segments(f"/localization/{name}", _segments(xy, z),
                                                                     colors=color, thickness=width)

    def update(self, snap: Snapshot) -> None:
        health, estimate = snap.localization, snap.base_estimate
        shown = health is not None and estimate is not None
        if health is not None and estimate is not None:
            color = UNTRUSTED_COLOR if health.untrusted else ESTIMATE_COLOR
            top = self.base_size_m[2] + Z_M
            self._lines("ellipse", ellipse(estimate[:2], health.covariance[:2, :2]), color, 0.02, top)
            self._lines("wedge", wedge(estimate, health.sigma_yaw_rad), color, 0.015, top)
        else:
            self._lines("ellipse", None, ESTIMATE_COLOR, 0.0)
            self._lines("wedge", None, ESTIMATE_COLOR, 0.0)
        truth = snap.base_true if shown else None
        self._draw_ghost(truth)

    def _draw_ghost(self, truth: np.ndarray | None) -> None:
        length, width, height = self.base_size_m
        if truth is None:
            self._lines("ghost_outline", None, GHOST_COLOR, 0.0)
            if self._ghost is not None:
                self._ghost.visible = False
            return
        self._lines("ghost_outline", footprint(truth, length, width), GHOST_COLOR, 0.03)
        if self._ghost is None:
            self._ghost = self.server.scene.add_box("/localization/ghost", color=GHOST_COLOR,
                                                    dimensions=(length, width, height), opacity=0.25,
                                                    cast_shadow=False, receive_shadow=False)
        half_yaw = truth[2] / 2
        self._ghost.position = (float(truth[0]), float(truth[1]), height / 2)
        self._ghost.wxyz = (math.cos(half_yaw), 0.0, 0.0, math.sin(half_yaw))
        self._ghost.visible = True
