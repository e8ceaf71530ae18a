"""Local Euclidean distance field around the robot (docs/method.md, 9a–9b), signed.

A grid of `window_m` (x, y centred on the robot; z from the floor up) at `voxel_m`. Occupied grid
nodes come from the map (inside an object's box, or nearest to an occupied voxel of the baseline).
With scipy's exact Euclidean distance transform:

    EDF = h · (EDT(free) − 1/2)        at free nodes      (distance to the nearest occupied node)
    EDF = −h · (EDT(occupied) − 1/2)   at occupied nodes  (depth to the nearest free node)

the transform of the free mask minus that of the occupied mask, as voxblox's and nvblox's ESDFs;
the half voxel puts the zero level between the last occupied and the first free node. Nodes marked
by surface points (objects mapped by their surface, the baseline's voxels) get the same half voxel:
the surface lies within half a voxel of its node either way, so this reads a voxel-rounding nearer
than the truth but never farther: without that shift the field was optimistic in places, which a safety
filter must not see (docs/decisions.md, "A signed EDF"). Negative inside objects, so the gradient there
points out. Truncated at ±theta_cutoff; outside the window
the `LocalEDF` reads theta_cutoff. The transform runs on the window grown by `pad_m` so that objects
just outside the window still shape the field near its edge.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy import ndimage

from core.types import LocalEDF


@dataclass(frozen=True)
class EDFGrid:
    """Node positions origin + voxel · (i, j, k) for indices below `shape`; `window` indexes the
    nodes of the requested window inside this (padded) grid."""

    origin: np.ndarray
    voxel: float
    shape: tuple[int, int, int]
    window: tuple[slice, slice, slice]

    @classmethod
    def around(cls, centre_xy: np.ndarray, window_m: tuple[float, float, float], voxel_m: float,
               pad_m: float = 0.0) -> EDFGrid:
        """The window around `centre_xy` (z from the floor up), grown by `pad_m` sideways and upwards
        and by one node below the floor (free: a box's bottom face is a surface, as in the ground truth)."""
        n = np.maximum(np.round(np.asarray(window_m) / voxel_m).astype(int) + 1, 2)
        pad = int(math.ceil(pad_m / voxel_m))
        origin = np.array([centre_xy[0] - window_m[0] / 2 - pad * voxel_m,
                           centre_xy[1] - window_m[1] / 2 - pad * voxel_m, -voxel_m])
        shape = (int(n[0] + 2 * pad), int(n[1] + 2 * pad), int(n[2] + pad + 1))
        window = (slice(pad, pad + n[0]), slice(pad, pad + n[1]), slice(1, 1 + n[2]))
        return cls(origin, voxel_m, shape, window)

    @property
    def window_origin(self) -> np.ndarray:
        return self.origin + self.voxel * np.array([w.start for w in self.window])

    def block(self, lo: np.ndarray, hi: np.ndarray) -> tuple[tuple[slice, slice, slice], list[np.ndarray]] | None:
        """Index slices of the nodes inside the world box [lo, hi] and their coordinates along each axis."""
        i0 = np.maximum(np.ceil((lo - self.origin) / self.voxel - 1e-9).astype(int), 0)
        i1 = np.minimum(np.floor((hi - self.origin) / self.voxel + 1e-9).astype(int) + 1, self.shape)
        if np.any(i1 <= i0):
            return None
        axes = [self.origin[a] + self.voxel * np.arange(i0[a], i1[a]) for a in range(3)]
        return (slice(i0[0], i1[0]), slice(i0[1], i1[1]), slice(i0[2], i1[2])), axes

    def empty(self) -> np.ndarray:
        return np.zeros(self.shape, dtype=bool)


def mark_boxes(grid: EDFGrid, occupied: np.ndarray, boxes: Iterable[tuple[np.ndarray, np.ndarray]]) -> None:
    """Set the nodes inside upright boxes, given as (pose 4×4, yaw about z only; full extent 3).

    Each half extent counts as at least half a voxel, so a thin box (the fit to the one face a camera
    has seen) marks the nodes nearest to it, as its surface points would, wherever the window's nodes
    fall; narrower than that it fell between the node rows and vanished from the field.

    The inside test is separable (x-y footprint × z range), so it is evaluated on the node axes by
    broadcasting instead of on every node of the block.
    """
    for pose, extent in boxes:
        # a box fitted to one seen face is a slab thinner than a voxel: it takes at least its nearest nodes
        half = np.maximum(np.asarray(extent) / 2, grid.voxel / 2) + 1e-9
        c, s, t = pose[0, 0], pose[1, 0], pose[:3, 3]
        reach = np.array([abs(c) * half[0] + abs(s) * half[1], abs(s) * half[0] + abs(c) * half[1], half[2]])
        found = grid.block(t - reach, t + reach)
        if found is None:
            continue
        index, (xs, ys, zs) = found
        dx, dy = xs[:, None] - t[0], ys[None, :] - t[1]
        footprint = (np.abs(c * dx + s * dy) <= half[0]) & (np.abs(-s * dx + c * dy) <= half[1])
        rows = np.abs(zs - t[2]) <= half[2]
        occupied[index] |= footprint[:, :, None] & rows[None, None, :]


def mark_points(grid: EDFGrid, occupied: np.ndarray, points: np.ndarray) -> None:
    """Set the node nearest to each point (N×3) inside the grid."""
    if len(points) == 0:
        return
    idx = np.rint((points - grid.origin) / grid.voxel).astype(int)
    ok = np.all((idx >= 0) & (idx < grid.shape), axis=1)
    idx = idx[ok]
    occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True


def mark_columns(grid: EDFGrid, occupied: np.ndarray, points: np.ndarray) -> None:
    """Set the node nearest to each point (N×3) and every node below it down to the floor (z = 0):
    the solid under a surface seen from above or the side, for objects that rest on the floor."""
    if len(points) == 0:
        return
    idx = np.rint((points - grid.origin) / grid.voxel).astype(int)
    ok = np.all((idx[:, :2] >= 0) & (idx[:, :2] < grid.shape[:2]), axis=1) & (idx[:, 2] >= 0)
    idx = idx[ok]
    top = np.full(grid.shape[:2], -1)
    np.maximum.at(top, (idx[:, 0], idx[:, 1]), np.minimum(idx[:, 2], grid.shape[2] - 1))
    floor = grid.window[2].start  # the node at z = 0
    k = np.arange(grid.shape[2])
    occupied |= (k[None, None, :] >= floor) & (k[None, None, :] <= top[:, :, None])


def depth_inside(occupied: np.ndarray) -> np.ndarray:
    """EDT of the occupied mask (distance in voxels from each occupied node to the nearest free one).

    Computed per connected occupied region on its bounding block grown by one node, which is exact
    (the nearest free node of a region lies within that block) and far cheaper than one transform of
    the whole, mostly free grid.
    """
    out = np.zeros(occupied.shape)
    labels, _ = cast(tuple[np.ndarray, int], ndimage.label(occupied))
    for region, block in enumerate(ndimage.find_objects(labels), start=1):
        grown = tuple(slice(max(b.start - 1, 0), min(b.stop + 1, n))
                      for b, n in zip(block, occupied.shape, strict=True))
        mask = labels[grown] == region
        d = cast(np.ndarray, ndimage.distance_transform_edt(mask))
        out[grown] = np.where(mask, d, out[grown])
    return out


def signed_distance(occupied: np.ndarray, voxel: float, cutoff: float) -> np.ndarray:
    """Signed EDF values (m) of an occupancy grid, truncated at ±cutoff (9a–9b, signed)."""
    if not occupied.any():
        return np.full(occupied.shape, cutoff)
    if occupied.all():
        return np.full(occupied.shape, -cutoff)
    outside = cast(np.ndarray, ndimage.distance_transform_edt(~occupied)) - 0.5
    inside = depth_inside(occupied) - 0.5
    values = np.where(occupied, -inside, outside) * voxel
    return np.clip(values, -cutoff, cutoff)


def local_edf(grid: EDFGrid, occupied: np.ndarray, cutoff: float) -> LocalEDF:
    """The `LocalEDF` of the window (the padded grid's EDT cropped back to the window)."""
    values = signed_distance(occupied, grid.voxel, cutoff)
    return LocalEDF(origin=grid.window_origin, voxel=grid.voxel, values=np.ascontiguousarray(values[grid.window]),
                    cutoff=cutoff)
