"""Segmentation of the non-floor points into object observations (docs/method.md, "Perception", step 3).

Points are voxelised at `voxel_m` (each voxel keeps the centroid of its points) and occupied voxels
are grouped by 26-connectivity with `scipy.ndimage.label` on the dense grid spanning them. Two boxes
are separate segments when at least one empty voxel lies between them.

On the same voxels open3d's DBSCAN with the same neighbourhood gives exactly the same clusters and is
several times slower, so we keep the labelling (docs/decisions.md, "Segmentation by connected-component
labelling"; `segmentation_*` figures of bench/mapping_rate.py). The dense grid stays small because points
come from within the depth range (at most (2 · range / voxel)³ cells).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy import ndimage

_CONNECTIVITY_26 = np.ones((3, 3, 3), dtype=bool)


@dataclass(frozen=True)
class VoxelCloud:
    """Points reduced to one centroid per occupied voxel: `centroids` (V×3), `counts` (V,), `keys` (V×3)."""

    centroids: np.ndarray
    counts: np.ndarray
    keys: np.ndarray


@dataclass(frozen=True)
class Segment:
    """One object observation: voxel centroids (V×3) of a connected cluster and their point counts."""

    points: np.ndarray
    counts: np.ndarray

    def sample(self, n: int) -> np.ndarray:
        """At most n of the points, evenly strided (costs and Delta are means: a sample estimates them)."""
        step = max(1, -(-len(self.points) // n))
        return self.points[::step]

    @property
    def lower(self) -> np.ndarray:
        return self.points.min(axis=0)

    @property
    def upper(self) -> np.ndarray:
        return self.points.max(axis=0)


def voxelise(points: np.ndarray, voxel_m: float) -> VoxelCloud:
    """One centroid per occupied voxel of size `voxel_m` (world-aligned grid)."""
    if len(points) == 0:
        return VoxelCloud(np.zeros((0, 3)), np.zeros(0, dtype=int), np.zeros((0, 3), dtype=np.int64))
    keys = np.floor(points / voxel_m).astype(np.int64)
    lo = keys.min(axis=0)
    dims = keys.max(axis=0) - lo + 1
    k = keys - lo
    lin = (k[:, 0] * dims[1] + k[:, 1]) * dims[2] + k[:, 2]
    uniq, inverse = np.unique(lin, return_inverse=True)
    counts = np.bincount(inverse, minlength=len(uniq))
    sums = np.stack([np.bincount(inverse, weights=points[:, i], minlength=len(uniq)) for i in range(3)], axis=1)
    voxel_keys = np.stack(np.unravel_index(uniq, tuple(dims)), axis=1) + lo
    return VoxelCloud(sums / counts[:, None], counts, voxel_keys)


def connected_voxels(keys: np.ndarray) -> np.ndarray:
    """Component label (0…n−1) of every voxel key (V×3) under 26-connectivity."""
    if len(keys) == 0:
        return np.zeros(0, dtype=int)
    lo = keys.min(axis=0)
    k = keys - lo
    grid = np.zeros(tuple(k.max(axis=0) + 1), dtype=bool)
    grid[k[:, 0], k[:, 1], k[:, 2]] = True
    labels, _ = cast(tuple[np.ndarray, int], ndimage.label(grid, structure=_CONNECTIVITY_26))
    return labels[k[:, 0], k[:, 1], k[:, 2]] - 1


def speckle_free(cloud: VoxelCloud, min_voxels: int) -> np.ndarray:
    """Keys (V×3) of the voxels in connected clusters of at least `min_voxels` voxels: isolated depth
    returns (speckle) are dropped, as `segment` drops them for the object map."""
    labels = connected_voxels(cloud.keys)
    if len(labels) == 0:
        return cloud.keys
    return cloud.keys[np.bincount(labels)[labels] >= min_voxels]


def segment(cloud: VoxelCloud, min_voxels: int) -> list[Segment]:
    """Connected clusters of occupied voxels with at least `min_voxels` voxels, largest first; clusters that
    only a thin bridge joins are cut apart (`cut_thin_bridges`)."""
    labels = cut_thin_bridges(cloud.keys, connected_voxels(cloud.keys), min_voxels)
    if len(labels) == 0:
        return []
    keep = labels >= 0
    cloud = VoxelCloud(cloud.centroids[keep], cloud.counts[keep], cloud.keys[keep])
    labels = np.unique(labels[keep], return_inverse=True)[1]
    order = np.argsort(labels, kind="stable")
    sizes = np.bincount(labels)
    groups = np.split(order, np.cumsum(sizes)[:-1])
    segments = [Segment(cloud.centroids[g], cloud.counts[g]) for g in groups if len(g) >= min_voxels]
    segments.sort(key=lambda s: -len(s.points))
    return segments


SURFACE_NEIGHBOURS = 4
"""A voxel with at least this many occupied 26-neighbours lies in a surface (a face's voxels have 5–8, a
one-voxel stroke's 2)."""


def cut_thin_bridges(keys: np.ndarray, labels: np.ndarray, min_voxels: int) -> np.ndarray:
    """Labels with each cluster that holds two or more surface parts of `min_voxels` joined only through
    thin strokes (voxels with fewer than `SURFACE_NEIGHBOURS` occupied neighbours: a line of flying or
    mis-placed returns) split into those parts; stroke voxels next to a part join it, the others get −1
    (dropped). Two boxes a stray line of points connects are two observations, never one object."""
    if len(keys) == 0:
        return labels
    n = int(labels.max()) + 1
    lo_c = np.full((n, 2), np.iinfo(np.int64).max)
    hi_c = np.full((n, 2), np.iinfo(np.int64).min)
    np.minimum.at(lo_c, labels, keys[:, :2])
    np.maximum.at(hi_c, labels, keys[:, :2])
    wide = np.hypot(*(hi_c - lo_c).T) >= BRIDGED_MIN_CELLS  # only a wide cluster can be two objects and a gap
    if not wide.any():
        return labels
    checked = wide[labels]
    out = cut_wide(keys[checked], labels[checked], min_voxels, int(labels.max()) + 1)
    labels = labels.copy()
    labels[checked] = out
    return labels


BRIDGED_MIN_CELLS = 20
"""Clusters narrower than this many voxels across (x-y diagonal: 1 m at 5 cm) are not checked for thin bridges."""


def cut_wide(keys: np.ndarray, labels: np.ndarray, min_voxels: int, first_new: int) -> np.ndarray:
    """`cut_thin_bridges` on the voxels of the wide clusters (new labels from `first_new` on)."""
    lo = keys.min(axis=0)
    k = keys - lo
    grid = np.zeros(tuple(k.max(axis=0) + 3), dtype=bool)
    k = k + 1
    grid[k[:, 0], k[:, 1], k[:, 2]] = True
    neighbours = np.rint(ndimage.uniform_filter(grid.astype(np.float32), size=3, mode="constant") * 27) - 1
    surface = grid & (neighbours >= SURFACE_NEIGHBOURS)
    parts, n_parts = cast(tuple[np.ndarray, int], ndimage.label(surface, structure=_CONNECTIVITY_26))
    if n_parts < 2:
        return labels
    part = parts[k[:, 0], k[:, 1], k[:, 2]]
    sizes = np.bincount(part, minlength=n_parts + 1)
    out = labels.copy()
    for cluster in np.unique(labels):
        members = labels == cluster
        big = [p for p in np.unique(part[members]) if p > 0 and sizes[p] >= min_voxels]
        if len(big) < 2:
            continue
        # each part keeps its own voxels and the stroke voxels touching it; the rest of the stroke goes
        grown = ndimage.grey_dilation(np.where(np.isin(parts, big), parts, 0), footprint=_CONNECTIVITY_26)
        owner = np.where(part > 0, part, grown[k[:, 0], k[:, 1], k[:, 2]])
        small = members & ~np.isin(owner, big)
        out[members] = first_new + owner[members]
        out[small] = -1
    return out
