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

from core.mapping.noise_shell import outweighed
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


# --- exact distances near seen surfaces (docs/decisions.md, "Mapped surfaces where they are") ----------

NEIGHBOUR_REACH = 3
"""A free node of the surface-column field also reads the points that the nearest occupied nodes of the nodes up
to this many above and below it stand for. Columns make the occupied nodes tall, and a column's top node stands
for a point up to half a voxel below it, so the nearest node in node distance is often one of a column that
stands for a point lower than its neighbour's (issue 26: by the aisle island's corner a column top 0.2 m below
the corner: the field read 0.92 m where the nearest surface point was 0.85 m away; ±1 and ±2 nodes still left
0.06 m; ±3 along x and y alone 0.062, along z alone 0.04)."""


def window_axes(grid: EDFGrid) -> list[np.ndarray]:
    """Coordinates of the window's nodes along x, y and z."""
    return [grid.origin[a] + grid.voxel * np.arange(s.start, s.stop) for a, s in enumerate(grid.window)]


def box_field(axes: list[np.ndarray], boxes: Iterable[tuple[np.ndarray, np.ndarray]], cutoff: float) -> np.ndarray:
    """Exact signed distance (m) at the nodes of `axes` to the nearest upright box (pose 4×4, yaw about z only;
    full extent 3), truncated at ±cutoff: min over boxes of the analytic box distance, negative inside.

    Separable: the footprint terms are (nx, ny), the height term (nz), so a box costs a few passes over the
    grid instead of a distance transform; no node rounding, so a face's distance is right to the millimetre.
    """
    xs, ys, zs = axes
    out = np.full((len(xs), len(ys), len(zs)), cutoff)
    for pose, extent in boxes:
        half = np.asarray(extent, float) / 2
        c, s, t = pose[0, 0], pose[1, 0], pose[:3, 3]
        dx, dy = xs[:, None] - t[0], ys[None, :] - t[1]
        qx, qy = np.abs(c * dx + s * dy) - half[0], np.abs(-s * dx + c * dy) - half[1]
        qz = np.abs(zs - t[2]) - half[2]
        flat = np.maximum(qx, 0.0) ** 2 + np.maximum(qy, 0.0) ** 2
        if np.sqrt(flat.min()) >= cutoff:
            continue
        outside = np.sqrt(flat[:, :, None] + (np.maximum(qz, 0.0) ** 2)[None, None, :])
        inside = np.minimum(np.maximum(np.maximum(qx, qy)[:, :, None], qz[None, None, :]), 0.0)
        np.minimum(out, outside + inside, out=out)
    return np.maximum(out, -cutoff)


def column_field(grid: EDFGrid, points: np.ndarray, cutoff: float, weights: np.ndarray | None = None,
                 shell_ratio: float = 0.0) -> np.ndarray:
    """Signed distance (m) on the window's nodes to the columns under surface points (N×3): the solid that
    `mark_columns` marks, measured to the surface itself rather than node to node.

    Each occupied node stands for a surface point: the centroid of the points in its cell, or, for column
    fill below the seen surface, its own height at the x-y centroid of its column's points. A free node's
    value is its distance to the point of its nearest occupied node (the feature transform of the free
    mask gives that node); an occupied node next to free space reads its signed offset from its point
    along the direction to that free space (positive when the node lies in front of the surface it stands
    for); deeper ones the transform's depth. On a wall seen from the side the point lies on the wall right
    in front of the node, so the values are the wall's distance to a few millimetres, where node-to-node
    distances read up to a voxel nearer. The nearest node in node distance need not stand for the nearest
    point (a point lies up to half a voxel from its node in each axis), so a free node also reads the points
    of the nearest nodes of the nodes up to `NEIGHBOUR_REACH` above and below it, and keeps the nearest.
    With `weights` and a `shell_ratio`, points whose EDF cell is outweighed that many times by a neighbour
    cell (the noise shell of a face seen from afar, `noise_shell.py`) are left out first. Truncated at ±cutoff.
    """
    if weights is not None and shell_ratio > 0.0:
        weights = np.asarray(weights, float)
        keep = ~outweighed(grid.origin, grid.voxel, grid.shape, points, weights, shell_ratio)
        points, weights = points[keep], weights[keep]
    occupied = grid.empty()
    mark_columns(grid, occupied, points)
    if not occupied.any():
        return np.full(tuple(s.stop - s.start for s in grid.window), cutoff)
    sx, sy, sz = _surface_points(grid, points, weights)
    nearest = cast(np.ndarray, ndimage.distance_transform_edt(~occupied, return_distances=False,
                                                              return_indices=True))
    i, j, k = nearest[(slice(None), *grid.window)]
    nodes = window_axes(grid)
    x, y, z = nodes[0][:, None, None], nodes[1][None, :, None], nodes[2][None, None, :]
    outside = np.sqrt((x - sx[i, j, k]) ** 2 + (y - sy[i, j, k]) ** 2 + (z - sz[i, j, k]) ** 2)
    _nearer_through_neighbours(grid, nearest, (sx, sy, sz), (x, y, z), outside)
    inside = -(depth_inside(occupied)[grid.window] - 0.5) * grid.voxel
    w = grid.window
    grown = tuple(slice(max(a.start - 1, 0), a.stop + 1) for a in w)
    inner = tuple(slice(a.start - g.start, a.stop - g.start) for a, g in zip(w, grown, strict=True))
    normal, sheet = _free_side(occupied[grown])
    normal, sheet = normal[(slice(None), *inner)], sheet[inner]
    dx, dy, dz = x - sx[w], y - sy[w], z - sz[w]
    offset = normal[0] * dx + normal[1] * dy + normal[2] * dz
    offset = np.where(sheet, 0.0, offset)  # a layer one node thin: which side is free is unknown, read 0
    rim = sheet | np.any(normal != 0.0, axis=0)
    inside = np.where(rim, offset, inside)
    values = np.where(occupied[w], inside, outside)
    return np.clip(values, -cutoff, cutoff)


def _nearer_through_neighbours(grid: EDFGrid, nearest: np.ndarray, surface: tuple[np.ndarray, ...],
                               nodes: tuple[np.ndarray, ...], outside: np.ndarray) -> None:
    """Lower each window node's `outside` (in place) to its distance to the points that the nearest occupied
    nodes of the nodes up to `NEIGHBOUR_REACH` above and below it stand for, where those differ from its own."""
    r = NEIGHBOUR_REACH
    flat = np.ravel_multi_index(tuple(nearest), grid.shape)
    flat = np.pad(flat, ((0, 0), (0, 0), (r, r)), mode="edge")  # shifts past the top or bottom repeat the last node
    window = (grid.window[0], grid.window[1], slice(grid.window[2].start + r, grid.window[2].stop + r))
    own = flat[window]
    points = [c.reshape(-1) for c in surface]
    full = np.broadcast_arrays(*nodes, outside)[:3]
    for step in (*range(-r, 0), *range(1, r + 1)):
        shifted = (window[0], window[1], slice(window[2].start + step, window[2].stop + step))
        other = flat[shifted]
        changed = other != own
        if not changed.any():
            continue
        idx = other[changed]
        d = np.sqrt(sum((full[c][changed] - points[c][idx]) ** 2 for c in range(3)))
        outside[changed] = np.minimum(outside[changed], d)


def _free_side(occupied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(3, …) unit direction from each occupied node towards its free face-neighbours (zero where none), and
    the mask of sheet nodes, whose free neighbours lie on opposite sides (there: the axis they lie along)."""
    free = ~occupied
    out = np.zeros((3, *occupied.shape))
    both = np.zeros((3, *occupied.shape), dtype=bool)
    for a in range(3):
        lead = [slice(None)] * 3
        lag = [slice(None)] * 3
        lead[a], lag[a] = slice(1, None), slice(None, -1)
        plus, minus = np.zeros(occupied.shape, dtype=bool), np.zeros(occupied.shape, dtype=bool)
        plus[tuple(lag)] = free[tuple(lead)]  # free neighbour at +1 along a
        minus[tuple(lead)] = free[tuple(lag)]  # free neighbour at −1 along a
        out[a] = (plus.astype(float) - minus) * occupied
        both[a] = plus & minus & occupied
    norm = np.sqrt(np.sum(out**2, axis=0))
    unit = np.divide(out, norm, out=np.zeros_like(out), where=norm > 0)
    sheet = (norm == 0) & np.any(both, axis=0)
    unit[:, sheet] = both[:, sheet]
    return unit, sheet


def _surface_points(grid: EDFGrid, points: np.ndarray,
                    weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The surface point each node of the padded grid stands for, as x, y and z arrays of the grid's shape:
    the centroid of the points in its cell, else its own height at the x-y centroid of its column's points
    (else the node itself)."""
    shape = grid.shape
    idx = np.rint((points - grid.origin) / grid.voxel).astype(int)
    ok = np.all((idx[:, :2] >= 0) & (idx[:, :2] < shape[:2]), axis=1) & (idx[:, 2] >= 0)
    idx, points = idx[ok], points[ok]
    w = np.ones(len(points)) if weights is None else np.asarray(weights, float)[ok]
    idx[:, 2] = np.minimum(idx[:, 2], shape[2] - 1)
    col = idx[:, 0] * shape[1] + idx[:, 1]
    n2, n3 = shape[0] * shape[1], int(np.prod(shape))
    cell = col * shape[2] + idx[:, 2]
    n_col = np.maximum(np.bincount(col, minlength=n2), 1).reshape(shape[0], shape[1], 1)
    n_cell = np.bincount(cell, minlength=n3).reshape(shape)
    w_cell = np.bincount(cell, w, n3).reshape(shape)
    has = n_cell > 0
    axes = [grid.origin[a] + grid.voxel * np.arange(shape[a]) for a in range(3)]
    out = []
    for a in range(3):
        per_cell = np.bincount(cell, points[:, a] * w, n3).reshape(shape) / np.where(has, w_cell, 1.0)
        if a < 2:
            column = np.bincount(col, points[:, a], n2).reshape(shape[0], shape[1], 1) / n_col
            empty_col = np.bincount(col, minlength=n2).reshape(shape[0], shape[1], 1) == 0
            fill = np.where(empty_col, axes[a][:, None, None] if a == 0 else axes[a][None, :, None], column)
        else:
            fill = axes[2][None, None, :]
        out.append(np.where(has, per_cell, fill))
    return out[0], out[1], out[2]
