"""Object submap M_i: the object's surface at `voxel_m` in the object's own frame (docs/method.md, eq. 1).

Each occupied voxel keeps the running centroid of the points that fell in it (so the surface is not
quantised to the voxel grid), weighted by each point's inverse depth-noise variance when it is given (a
return from 3 m is 9× noisier than one from 1 m: depth noise spreads a far face's points over a few voxels
in depth, and the near returns that later fall in the same voxels pull its centroid onto the face), the
number of points fused, their summed weight, a hit count and the number of observations that saw through it since
it was last hit. Because the voxels live in the object frame, a registration that moves the object
moves its whole submap with it.

The distance field M_i is evaluated on demand from a KD-tree of the voxel centroids, distance to the
nearest surface voxel. The tree is rebuilt after carving or once the submap has grown by
`TREE_REBUILD_GROWTH` (depth noise adds a few shell voxels every frame; centroids only move within
their voxel, and the object's box covers what a slightly stale tree misses): the object EDF that POCD
compares observations against; voxels with |M_i| ≤ theta_zero are the surface by construction.
"""

from __future__ import annotations

import numpy as np

# scipy re-exports cKDTree from a compiled module whose names pyright cannot see.
from scipy.spatial import cKDTree  # pyright: ignore[reportAttributeAccessIssue]

_BITS = 21
_OFFSET = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1

TREE_REBUILD_GROWTH = 0.05


def pack(keys: np.ndarray) -> np.ndarray:
    """Pack integer voxel keys (N×3, each within ±2^20) into one int64 each."""
    k = keys.astype(np.int64) + _OFFSET
    return (k[:, 0] << (2 * _BITS)) | (k[:, 1] << _BITS) | k[:, 2]


def unpack(keys: np.ndarray) -> np.ndarray:
    """Integer voxel keys (N×3) from packed int64 keys (inverse of `pack`)."""
    k = np.stack([(keys >> (2 * _BITS)) & _MASK, (keys >> _BITS) & _MASK, keys & _MASK], axis=1)
    return k - _OFFSET


class ObjectSubmap:
    """Surface voxels of one object in its frame: centroids (V×3), hit and seen-through counts."""

    def __init__(self, voxel_m: float) -> None:
        self.voxel_m = voxel_m
        self._keys = np.zeros(0, dtype=np.int64)  # sorted packed keys
        self._sums = np.zeros((0, 3))  # weighted sums of the points
        self._weights = np.zeros(0)
        self._counts = np.zeros(0)
        self.hits = np.zeros(0, dtype=np.int32)
        self.misses = np.zeros(0, dtype=np.int32)
        self._tree: cKDTree | None = None
        self._tree_size = 0

    def __len__(self) -> int:
        return len(self._keys)

    @property
    def counts(self) -> np.ndarray:
        """Points fused into each voxel (V,)."""
        return self._counts

    @property
    def weights(self) -> np.ndarray:
        """Summed weight of the points fused into each voxel (V,)."""
        return self._weights

    @property
    def points(self) -> np.ndarray:
        """Surface voxel centroids (V×3) in the object frame."""
        return self._sums / self._weights[:, None]

    def integrate(self, points: np.ndarray, weights: np.ndarray | None = None) -> None:
        """Add observed surface points (N×3, object frame), each with its weight (N,; 1 if not given):
        weighted centroids move, point counts and weights add up, hit counts grow."""
        if len(points) == 0:
            return
        w = np.ones(len(points)) if weights is None else np.asarray(weights, float)
        keys = pack(np.floor(points / self.voxel_m).astype(np.int64))
        uniq, inverse = np.unique(keys, return_inverse=True)
        sums = np.stack([np.bincount(inverse, weights=points[:, i] * w, minlength=len(uniq)) for i in range(3)], axis=1)
        wsum = np.bincount(inverse, weights=w, minlength=len(uniq))
        counts = np.bincount(inverse, minlength=len(uniq)).astype(float)
        pos = np.searchsorted(self._keys, uniq)
        found = pos < len(self._keys)
        found[found] = self._keys[pos[found]] == uniq[found]
        old = pos[found]
        self._sums[old] += sums[found]
        self._weights[old] += wsum[found]
        self._counts[old] += counts[found]
        self.hits[old] += 1
        self.misses[old] = 0
        new = ~found
        if np.any(new):
            self._append(uniq[new], sums[new], wsum[new], counts[new])

    def _append(self, keys: np.ndarray, sums: np.ndarray, weights: np.ndarray, counts: np.ndarray) -> None:
        all_keys = np.concatenate([self._keys, keys])
        order = np.argsort(all_keys, kind="stable")
        self._keys = all_keys[order]
        self._sums = np.concatenate([self._sums, sums])[order]
        self._weights = np.concatenate([self._weights, weights])[order]
        self._counts = np.concatenate([self._counts, counts])[order]
        self.hits = np.concatenate([self.hits, np.ones(len(keys), dtype=np.int32)])[order]
        self.misses = np.concatenate([self.misses, np.zeros(len(keys), dtype=np.int32)])[order]

    def mark_seen_through(self, mask: np.ndarray) -> None:
        """Count one seen-through observation for the voxels in `mask` (V,), in `points` order."""
        self.misses[mask] += 1

    def carve(self, min_misses: int) -> int:
        """Delete voxels seen through in `min_misses` observations since they were last hit; returns how many."""
        gone = self.misses >= min_misses
        n = int(gone.sum())
        if n:
            keep = ~gone
            self._keys, self._sums, self._counts = self._keys[keep], self._sums[keep], self._counts[keep]
            self._weights = self._weights[keep]
            self.hits, self.misses = self.hits[keep], self.misses[keep]
            self._tree = None
        return n

    def distance(self, points: np.ndarray, upper_m: float = np.inf) -> np.ndarray:
        """M_i at points (N×3, object frame): distance to the nearest surface voxel, at most `upper_m`."""
        if len(self._keys) == 0:
            return np.full(len(points), upper_m)
        tree = self._tree
        if tree is None or len(self._keys) > (1.0 + TREE_REBUILD_GROWTH) * self._tree_size:
            tree = self._tree = cKDTree(self.points)
            self._tree_size = len(self._keys)
        d, _ = tree.query(points, k=1, distance_upper_bound=upper_m)
        return np.minimum(d, upper_m)
