"""Frozen surfaces: the reference as localization keeps it, so that it does not follow the drift.

The map places what it sees at the pose the loop gives it, and its own per-object registration re-places an
object onto its newest observation; registering against the map's surfaces as they are now measures little
more than the drift the map has already taken in. So each trusted object's surface is frozen where it was when
first trusted, while the pose's std was at most `freeze_sigma_m`, and kept there:
  - later, the object's surface may only grow: points of the map's surface farther than `grow_m` from the
    frozen ones (a wall seen further along) join it; points near the frozen surface are the same surface,
    wherever the map has put it since, and are not taken;
  - an object the map no longer trusts or has removed (POCD re-creates a moved one under a new id, frozen
    afresh) leaves, and so does one that localization found disagreeing (`forget`): it is frozen again from
    the map once it is trusted and no longer excluded.
Like a keyframe map without loop closure: coming back to surfaces frozen earlier pulls the pose back to where
it was then (the end of a lap, a second lap), and what was frozen while the pose had drifted stays so.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import small_gicp  # pyright: ignore[reportMissingImports]  (a compiled module without stubs)

from core.types import ReferenceSurface


class FrozenSurfaces:
    """Object id → its frozen surface points (world), and the `ReferenceSurface` they make."""

    def __init__(self, freeze_sigma_m: float, grow_m: float) -> None:
        self.freeze_sigma_m = freeze_sigma_m
        self.grow_m = grow_m
        self.points: dict[int, np.ndarray] = {}
        self._trees: dict[int, tuple[small_gicp.PointCloud, small_gicp.KdTree]] = {}
        """Each object's points as small_gicp's cloud (kept alive with its tree) and k-d tree."""
        self._surface = ReferenceSurface(0.0, np.zeros((0, 3)), np.zeros(0, int))
        self._seen: tuple[int, float] | None = None
        self.version = 0
        """Counts the changes of the frozen reference (a cache key)."""

    @property
    def surface(self) -> ReferenceSurface:
        """The frozen points as a reference surface."""
        return self._surface

    def update(self, surface: ReferenceSurface | None, sigma_m: float, excluded: Iterable[int] = ()
               ) -> ReferenceSurface:
        """Take in the map's trusted surfaces (once per surface handed over) with the pose's current std σ (m),
        objects in `excluded` (disagreeing lately) not frozen again yet; the frozen reference (the same object
        while nothing changed)."""
        if surface is None:
            return self._surface
        key = (id(surface), surface.t)
        if key == self._seen:
            return self._surface
        self._seen = key
        ids = np.asarray(surface.object_ids, int)
        pts = np.asarray(surface.points, float)
        live = set(np.unique(ids).tolist())
        gone = [i for i in self.points if i not in live]
        for i in gone:
            self._drop(i)
        changed = bool(gone)
        if sigma_m <= self.freeze_sigma_m:
            skip = set(excluded)
            for i in sorted(live):
                if i < 0 or i in skip:
                    continue  # not an object (nothing to follow it by), or disagreeing lately
                mine = pts[ids == i]
                if i in self.points:
                    _, sq = self._trees[i][1].batch_nearest_neighbor_search(np.ascontiguousarray(mine), num_threads=1)
                    mine = mine[np.asarray(sq, float).reshape(-1) > self.grow_m**2]
                if len(mine):
                    self._add(i, mine)
                    changed = True
        if changed:
            self._rebuild(surface.t)
        return self._surface

    def forget(self, ids: Iterable[int]) -> None:
        """Objects found off their surface (moved): frozen again from the map once trusted and not excluded."""
        dropped = [i for i in ids if i in self.points]
        for i in dropped:
            self._drop(i)
        if dropped:
            self._rebuild(self._surface.t)

    def _add(self, i: int, points: np.ndarray) -> None:
        if i in self.points:
            points = np.vstack([self.points[i], points])
        self.points[i] = points = np.ascontiguousarray(points, dtype=np.float64)
        cloud = small_gicp.PointCloud(points)
        self._trees[i] = (cloud, small_gicp.KdTree(cloud, num_threads=1))

    def _drop(self, i: int) -> None:
        self.points.pop(i, None)
        self._trees.pop(i, None)

    def _rebuild(self, t: float) -> None:
        self.version += 1
        ids = sorted(self.points)
        if not ids:
            self._surface = ReferenceSurface(t, np.zeros((0, 3)), np.zeros(0, int))
            return
        self._surface = ReferenceSurface(t, np.vstack([self.points[i] for i in ids]),
                                         np.concatenate([np.full(len(self.points[i]), i, int) for i in ids]))
