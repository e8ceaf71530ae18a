"""Box completion from partial views: how far an object may reach where it has not been seen.

A box-like object is mapped as the upright box fitted around the surface seen so far (`box_fit.py`).
Seen from one side only, that box is the seen face: a slab of no depth, with free space right behind it
in the EDF, inside the real object. Its unseen parts are completed conservatively (the object's
`solid` box), in the object frame:

- behind: along each horizontal box axis on which the object is thinner than `assumed_depth_m` and has
  been seen from one side only (every camera that saw it on the same side of it), the box reaches on,
  away from the cameras, to that depth;
- below: the box reaches down to the floor (a box's lower part is often hidden behind another box or
  below the camera's view; the fit itself snaps to the floor only within the floor filter's band);
- above: if no camera that saw it was higher than its top, the box reaches `assumed_depth_m` higher (a
  box taller than the hand camera shows its front face only up to the image's upper edge).

Each reach stops short of free space seen there: sample points on a `step_m` grid of the object frame
inside the reach, at least a step in from its sides, are checked against depth frames; a sample seen
through in `confirm` checks (and not hit since) is free. Behind a face the reach ends at the nearest free
sample, below the box at the highest, above it at the lowest. So a box seen from two sides gets its
real depth (the rays past
its far edge see free space behind it), a box floating at hand height keeps the space under it free once
rays have passed under it, and a face seen alone stands for a box `assumed_depth_m` deep. Free samples
never cut into the fitted box: what was seen stays.
"""

from __future__ import annotations

import numpy as np

from core.mapping.box_fit import BoxFit
from core.mapping.submap import pack, unpack

CAMERA_CELL_M = 0.25
"""Camera positions are kept once per cell of this size (object frame)."""
MAX_CAMERAS = 256


class Completion:
    """The cameras that saw an object and the free space seen where its unseen parts could be."""

    def __init__(self, step_m: float, assumed_depth_m: float, confirm: int) -> None:
        self.step_m = step_m
        self.assumed_depth_m = assumed_depth_m
        self.confirm = confirm
        self.cameras = np.zeros((0, 3))
        """Object-frame positions of the cameras that saw the object (one per `CAMERA_CELL_M` cell)."""
        self._camera_keys = np.zeros(0, dtype=np.int64)
        self._keys = np.zeros(0, dtype=np.int64)  # sorted packed sample keys seen through ...
        self._counts = np.zeros(0, dtype=np.int32)  # ... this many times since last hit
        self.version = 0
        """Changes whenever the completed box may have changed (new camera side, new free sample)."""

    # --- evidence ---------------------------------------------------------------------------------

    def saw_from(self, camera: np.ndarray) -> None:
        """A camera at this object-frame position observed the object."""
        key = pack(np.floor(np.asarray(camera, float)[None] / CAMERA_CELL_M).astype(np.int64))
        if np.isin(key, self._camera_keys)[0]:
            return
        self._camera_keys = np.append(self._camera_keys, key)[-MAX_CAMERAS:]
        self.cameras = np.vstack([self.cameras, camera])[-MAX_CAMERAS:]
        self.version += 1

    def mark(self, samples: np.ndarray, through: np.ndarray, hit: np.ndarray) -> None:
        """Record one check of `samples` (object frame, from `samples`): those seen through count once
        more, those hit (a surface there) start again."""
        keys = self._key(samples)
        if np.any(hit):
            gone = np.isin(self._keys, keys[hit])
            self._keys, self._counts = self._keys[~gone], self._counts[~gone]
        seen = np.unique(keys[through & ~hit])
        if len(seen) == 0:
            return
        before = self.free_count()
        pos = np.searchsorted(self._keys, seen)
        found = pos < len(self._keys)
        found[found] = self._keys[pos[found]] == seen[found]
        self._counts[pos[found]] += 1
        new = seen[~found]
        if len(new):
            keys_all = np.concatenate([self._keys, new])
            order = np.argsort(keys_all, kind="stable")
            self._keys = keys_all[order]
            self._counts = np.concatenate([self._counts, np.ones(len(new), dtype=np.int32)])[order]
        if self.free_count() != before:
            self.version += 1

    def free_count(self) -> int:
        return int(np.sum(self._counts >= self.confirm))

    def free_points(self) -> np.ndarray:
        """Object-frame sample points confirmed free (F×3)."""
        return unpack(self._keys[self._counts >= self.confirm]).astype(float) * self.step_m

    def _key(self, points: np.ndarray) -> np.ndarray:
        return pack(np.rint(points / self.step_m).astype(np.int64))

    # --- the completed box -----------------------------------------------------------------------

    def reach(self, fit: BoxFit, floor_z: float) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi): the completed box's bounds in the fitted box's frame (the fit is −half … +half)."""
        h = fit.half
        lo, hi = -h.copy(), h.copy()
        cams = (self.cameras - fit.centre) @ fit.rotation
        for a in (0, 1):
            extra = self.assumed_depth_m - 2 * h[a]
            if extra <= 0.0 or len(cams) == 0:
                continue
            minus, plus = np.any(cams[:, a] < -h[a]), np.any(cams[:, a] > h[a])
            if minus and not plus:
                hi[a] += extra
            elif plus and not minus:
                lo[a] -= extra
        lo[2] = min(lo[2], floor_z - fit.centre[2])
        if len(cams) and not np.any(cams[:, 2] > h[2]):
            hi[2] += self.assumed_depth_m
        free = (self.free_points() - fit.centre) @ fit.rotation if self.free_count() else np.zeros((0, 3))
        if len(free):
            self._cut(free, h, lo, hi)
        return lo, hi

    def _cut(self, free: np.ndarray, h: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """Shorten each reach to the free sample nearest to the fitted box (in place)."""
        half_step = self.step_m / 2
        beside_fit_z = np.abs(free[:, 2]) <= h[2]
        for a in (0, 1):
            b = 1 - a
            across = beside_fit_z & (free[:, b] >= lo[b]) & (free[:, b] <= hi[b])
            ahead = free[across & (free[:, a] > h[a]) & (free[:, a] <= hi[a]), a]
            if len(ahead):
                hi[a] = max(h[a], ahead.min() - half_step)
            behind = free[across & (free[:, a] < -h[a]) & (free[:, a] >= lo[a]), a]
            if len(behind):
                lo[a] = min(-h[a], behind.max() + half_step)
        over = np.all((free[:, :2] >= lo[:2]) & (free[:, :2] <= hi[:2]), axis=1)
        below = free[over & (free[:, 2] < -h[2]) & (free[:, 2] >= lo[2]), 2]
        if len(below):
            lo[2] = min(-h[2], below.max() + half_step)
        above = free[over & (free[:, 2] > h[2]) & (free[:, 2] <= hi[2]), 2]
        if len(above):
            hi[2] = max(h[2], above.min() - half_step)

    def box(self, fit: BoxFit, floor_z: float) -> BoxFit:
        """The completed (solid) box in the object frame: the fit and the reaches that remain."""
        lo, hi = self.reach(fit, floor_z)
        centre = fit.centre + fit.rotation @ ((lo + hi) / 2)
        return BoxFit(centre=centre, yaw=fit.yaw, extent=hi - lo)

    def samples(self, fit: BoxFit, floor_z: float) -> np.ndarray:
        """Object-frame grid points inside the reaches (beyond half a step from the fit, a step in from the
        reaches' sides): where free space, if seen, shortens them."""
        lo, hi = self.reach(fit, floor_z)
        h, s = fit.half, self.step_m
        if np.all(lo >= -h - 1e-9) and np.all(hi <= h + 1e-9):
            return np.zeros((0, 3))
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        world = corners @ fit.rotation.T + fit.centre
        k0, k1 = np.floor(world.min(axis=0) / s).astype(int), np.ceil(world.max(axis=0) / s).astype(int)
        axes = [np.arange(k0[i], k1[i] + 1) * s for i in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        u = (grid - fit.centre) @ fit.rotation
        beyond = (u > h + s / 2) & (u <= hi), (u < -h - s / 2) & (u >= lo)  # per axis, on either side
        inside = (u >= lo + s) & (u <= hi - s)  # a step in from the reaches' sides
        beside_fit_z = np.abs(u[:, 2]) <= h[2] - s
        keep = np.zeros(len(u), dtype=bool)
        for a in (0, 1):
            b = 1 - a
            keep |= (beyond[0][:, a] | beyond[1][:, a]) & inside[:, b] & beside_fit_z
        keep |= (beyond[0][:, 2] | beyond[1][:, 2]) & inside[:, 0] & inside[:, 1]
        return grid[keep]
