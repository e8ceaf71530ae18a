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

from core.mapping.noise_shell import outweighed_cells
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
    _mark_column_nodes(grid, occupied, ColumnPoints.over(grid, points).nodes)


def _mark_column_nodes(grid: EDFGrid, occupied: np.ndarray, nodes: np.ndarray) -> None:
    """`mark_columns` for the points' nodes (N×3, inside the grid): each column up to its highest node."""
    top = np.full(grid.shape[:2], -1)
    np.maximum.at(top, (nodes[:, 0], nodes[:, 1]), nodes[:, 2])
    floor = grid.window[2].start  # the node at z = 0
    k = np.arange(grid.shape[2])
    occupied |= (k[None, None, :] >= floor) & (k[None, None, :] <= top[:, :, None])


@dataclass(frozen=True)
class ColumnPoints:
    """Surface points over the grid's columns: the points (N×3), their weights (ones if none were given), their
    nearest nodes (N×3; heights above the grid count in its top layer) and those nodes' flat indices.

    Points beside the grid or below its lowest layer are left out. The columns, the noise shell and the surface
    points all read these nodes, so they are found once a call; the bounds are tested axis by axis (an `np.all`
    over an (N, 2) index array cost ten times as much)."""

    points: np.ndarray
    weights: np.ndarray
    nodes: np.ndarray
    flat: np.ndarray

    @classmethod
    def over(cls, grid: EDFGrid, points: np.ndarray, weights: np.ndarray | None = None) -> ColumnPoints:
        idx = np.rint((points - grid.origin) / grid.voxel).astype(int)
        i, j, k = idx[:, 0], idx[:, 1], idx[:, 2]
        ok = (i >= 0) & (i < grid.shape[0]) & (j >= 0) & (j < grid.shape[1]) & (k >= 0)
        w = np.ones(len(points)) if weights is None else np.asarray(weights, float)
        idx = idx[ok]
        np.minimum(idx[:, 2], grid.shape[2] - 1, out=idx[:, 2])
        flat = (idx[:, 0] * grid.shape[1] + idx[:, 1]) * grid.shape[2] + idx[:, 2]
        return cls(points[ok], w[ok], idx, flat)

    def subset(self, keep: np.ndarray) -> ColumnPoints:
        """The points where `keep` (N,) is set, in their order."""
        return ColumnPoints(self.points[keep], self.weights[keep], self.nodes[keep], self.flat[keep])


def depth_inside(occupied: np.ndarray) -> np.ndarray:
    """EDT of the occupied mask (distance in voxels from each occupied node to the nearest free one), in any
    number of dimensions.

    Computed on the bounding block of the occupied nodes grown by one node, which is exact (a free node
    outside that block projects onto its border to a free node no farther from any occupied node) and far
    cheaper than one transform of the whole, mostly free grid. One transform of that block also beat one per
    connected region (which needed a labelling first): 1.1 against 1.6 ms on the aisle's column grids."""
    out = np.zeros(occupied.shape)
    axes = range(occupied.ndim)
    filled = [np.flatnonzero(occupied.any(axis=tuple(b for b in axes if b != a))) for a in axes]
    if len(filled[0]) == 0:
        return out
    block = tuple(slice(max(int(f[0]) - 1, 0), min(int(f[-1]) + 2, n))
                  for f, n in zip(filled, occupied.shape, strict=True))
    out[block] = cast(np.ndarray, ndimage.distance_transform_edt(occupied[block]))
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
    cells = ColumnPoints.over(grid, points, weights)
    if weights is not None and shell_ratio > 0.0:
        cells = cells.subset(~outweighed_cells(cells.flat, cells.weights, grid.shape, shell_ratio))
    occupied = grid.empty()
    _mark_column_nodes(grid, occupied, cells.nodes)
    if not occupied.any():
        return np.full(tuple(s.stop - s.start for s in grid.window), cutoff)
    nodes = np.flatnonzero(occupied)
    surface = _surface_points(grid, cells, nodes)
    row_of = np.zeros(occupied.size, dtype=np.intp)
    row_of[nodes] = np.arange(len(nodes))
    ijk = np.unravel_index(nodes, grid.shape)
    rows = row_of[_nearest_nodes(grid, occupied, ijk, NEIGHBOUR_REACH)]
    values = _outside(grid, rows, surface, NEIGHBOUR_REACH)
    at, inside = _inside(grid, occupied, ijk, surface)
    values.reshape(-1)[at] = inside
    return np.clip(values, -cutoff, cutoff, out=values)


def _nearest_nodes(grid: EDFGrid, occupied: np.ndarray, nodes: tuple[np.ndarray, ...], reach: int) -> np.ndarray:
    """Flat index of the nearest occupied node (the feature transform of the free mask) of each node of the
    window's x-y and of its z range grown by `reach` each way; past the grid's bottom or top the last layer
    repeats. `nodes` are the occupied nodes' indices (i, j, k).

    The transform runs on the bounding block of those nodes and of the nodes asked for, not on the whole
    padded grid (a quarter to a third smaller on the aisle's grids). The same features: every occupied node is
    inside the block, and a line of the grid cut by the block loses only nodes with no occupied node in their
    row, which no node's nearest can be."""
    wx, wy, wz = grid.window
    lo = np.minimum([wx.start, wy.start, max(wz.start - reach, 0)], [int(n.min()) for n in nodes])
    hi = np.maximum([wx.stop, wy.stop, min(wz.stop + reach, grid.shape[2])], [int(n.max()) + 1 for n in nodes])
    block = tuple(slice(int(a), int(b)) for a, b in zip(lo, hi, strict=True))
    nearest = cast(np.ndarray, ndimage.distance_transform_edt(~occupied[block], return_distances=False,
                                                              return_indices=True))
    zs = np.clip(np.arange(wz.start - reach, wz.stop + reach), 0, grid.shape[2] - 1) - lo[2]
    i, j, k = (nearest[a, wx.start - lo[0]:wx.stop - lo[0], wy.start - lo[1]:wy.stop - lo[1]][:, :, zs] + lo[a]
               for a in range(3))
    return (i * grid.shape[1] + j) * grid.shape[2] + k


def _outside(grid: EDFGrid, rows: np.ndarray, surface: np.ndarray, reach: int) -> np.ndarray:
    """Distance (m) from each window node to the nearest of the surface points (3×K) that the nearest occupied
    nodes (`rows` into `surface`, from `_nearest_nodes`) of the nodes up to `reach` above and below it stand for.

    The nearest node in node distance need not stand for the nearest point: columns make the occupied nodes
    tall, and a point lies up to half a voxel from its node in each axis (see `NEIGHBOUR_REACH`). Squared
    distances are compared and one square root taken at the end (the root is monotone and correctly rounded,
    so this equals the minimum of the roots)."""
    x, y, z = window_axes(grid)
    x, y, z = x[:, None, None], y[None, :, None], z[None, None, :]
    px, py, pz = (surface[a][rows] for a in range(3))
    shape = (len(x), y.shape[1], z.shape[2])
    best, total, term = np.full(shape, np.inf), np.empty(shape), np.empty(shape)  # reused: no fresh temporaries
    for step in range(2 * reach + 1):
        part = (slice(None), slice(None), slice(step, step + shape[2]))
        np.square(np.subtract(x, px[part], out=total), out=total)
        total += np.square(np.subtract(y, py[part], out=term), out=term)
        total += np.square(np.subtract(z, pz[part], out=term), out=term)
        np.minimum(best, total, out=best)
    return np.sqrt(best, out=best)


def _inside(grid: EDFGrid, occupied: np.ndarray, nodes: tuple[np.ndarray, ...],
            surface: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flat window indices of the occupied nodes (`nodes` as (i, j, k), surface points 3×K) inside the window, and their
    signed values: next to free space the signed offset from the node's point along the direction to that free
    space (0 on a layer one node thin, whose free side is unknown), deeper the transform's depth."""
    wx, wy, wz = grid.window
    i, j, k = nodes
    keep = (i >= wx.start) & (i < wx.stop) & (j >= wy.start) & (j < wy.stop) & (k >= wz.start) & (k < wz.stop)
    i, j, k, own = i[keep], j[keep], k[keep], surface[:, keep]
    normal, sheet = _free_side(occupied, (i, j, k))
    dx, dy, dz = (grid.origin[a] + grid.voxel * n - own[a] for a, n in enumerate((i, j, k)))
    values = np.where(sheet, 0.0, normal[0] * dx + normal[1] * dy + normal[2] * dz)
    deep = ~(sheet | np.any(normal != 0.0, axis=0))
    if deep.any():
        depth = depth_inside(occupied)[i[deep], j[deep], k[deep]]
        values[deep] = -(depth - 0.5) * grid.voxel
    at = ((i - wx.start) * (wy.stop - wy.start) + (j - wy.start)) * (wz.stop - wz.start) + (k - wz.start)
    return at, values


def _free_side(occupied: np.ndarray, at: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(3, n) unit direction from each occupied node at indices `at` towards its free face-neighbours (zero
    where none), and the mask of sheet nodes, whose free neighbours lie on opposite sides (there: the axis they
    lie along). Beyond the grid's faces nothing counts as free."""
    shape = tuple(n + 2 for n in occupied.shape)
    bordered = np.pad(occupied, 1, constant_values=True).reshape(-1)
    here = np.ravel_multi_index(tuple(a + 1 for a in at), shape)
    out = np.zeros((3, len(here)))
    both = np.zeros((3, len(here)), dtype=bool)
    for a, stride in enumerate((shape[1] * shape[2], shape[2], 1)):
        plus, minus = ~bordered[here + stride], ~bordered[here - stride]
        out[a] = plus.astype(float) - minus
        both[a] = plus & minus
    norm = np.sqrt(np.sum(out**2, axis=0))
    unit = np.divide(out, norm, out=np.zeros_like(out), where=norm > 0)
    sheet = (norm == 0) & np.any(both, axis=0)
    unit[:, sheet] = both[:, sheet]
    return unit, sheet


def _surface_points(grid: EDFGrid, cells: ColumnPoints, at: np.ndarray) -> np.ndarray:
    """The surface point (3×K) each node of flat index `at` stands for: the weighted centroid of the points in
    its cell, else its own height at the x-y centroid of its column's points (else the node itself).

    Sums per cell and per column over the whole grid (one `bincount` each), read only at `at`."""
    shape = grid.shape
    n2, n3 = shape[0] * shape[1], int(np.prod(shape))
    col, at_col = cells.flat // shape[2], at // shape[2]
    has = np.bincount(cells.flat, minlength=n3)[at] > 0
    w_cell = np.where(has, np.bincount(cells.flat, cells.weights, n3)[at], 1.0)
    in_col = np.bincount(col, minlength=n2)[at_col]
    node = np.unravel_index(at, shape)
    out = np.empty((3, len(at)))
    for a in range(3):
        per_cell = np.bincount(cells.flat, cells.points[:, a] * cells.weights, n3)[at] / w_cell
        own = grid.origin[a] + grid.voxel * node[a]
        if a < 2:
            column = np.bincount(col, cells.points[:, a], n2)[at_col] / np.maximum(in_col, 1)
            own = np.where(in_col == 0, own, column)
        out[a] = np.where(has, per_cell, own)
    return out
