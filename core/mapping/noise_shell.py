"""The noise shell of a face seen from afar: surface points the EDF's surface columns leave out.

Depth noise grows as range² (σ = 0.005 z², 4.5 cm at 3 m), so a face seen from afar spreads its returns over
a few 5 cm submap voxels in depth. Each voxel's centroid is weighted by its points' inverse noise variance
(`tracked_object.noise_weight`), but a voxel a few centimetres in front of the face that only far returns ever
reached stands alone, with a fraction of the weight of the voxels on the face behind it. Marked as a surface
column, it puts the surface that far in front of the face (issue 26: on a lap of the aisle 8–10 % of the
rows' well-supported voxels lay 5–10 cm in front of the true face, with a tenth of the median weight).

Here a point is left out when the EDF cell it falls in weighs less than 1/`ratio` of the heaviest cell among
its 26 neighbours: that neighbour holds the same face, seen from nearer or more often. The test is relative,
so a face that was only ever seen from afar (all its cells light) keeps every cell.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def outweighed(origin: np.ndarray, voxel: float, shape: tuple[int, int, int], points: np.ndarray,
               weights: np.ndarray, ratio: float) -> np.ndarray:
    """Mask (N,) of the points (N×3) whose grid cell (nearest node of `origin + voxel · (i, j, k)` within
    `shape`; heights above the grid count in its top layer) weighs less than 1/`ratio` of a neighbour cell.
    Points beside or below the grid are never outweighed."""
    idx = np.rint((points - origin) / voxel).astype(int)
    ok = np.all((idx[:, :2] >= 0) & (idx[:, :2] < shape[:2]), axis=1) & (idx[:, 2] >= 0)
    out = np.zeros(len(points), dtype=bool)
    if not ok.any():
        return out
    idx = idx[ok]
    idx[:, 2] = np.minimum(idx[:, 2], shape[2] - 1)
    flat = np.ravel_multi_index((idx[:, 0], idx[:, 1], idx[:, 2]), shape)
    out[ok] = outweighed_cells(flat, np.asarray(weights, float)[ok], shape, ratio)
    return out


def outweighed_cells(flat: np.ndarray, weights: np.ndarray, shape: tuple[int, int, int], ratio: float) -> np.ndarray:
    """Mask (N,) of the points, given by the flat index of their cell in `shape` and their weight, whose cell
    weighs less than 1/`ratio` of the heaviest of its 26 neighbours: `outweighed` once the cells are known (the
    surface columns find the cells once for the shell, the columns and the surface points).

    The neighbourhood maximum is read only at cells that hold points, so the filter runs on their bounding block
    grown by one cell: every cell beyond it is empty, as the filter's constant-zero border is."""
    if len(flat) == 0:
        return np.zeros(0, dtype=bool)
    cell = np.bincount(flat, weights, int(np.prod(shape))).reshape(shape)
    ijk = np.unravel_index(flat, shape)
    block = tuple(slice(max(int(n.min()) - 1, 0), int(n.max()) + 2) for n in ijk)
    heaviest = ndimage.maximum_filter(cell[block], size=3, mode="constant", cval=0.0)
    at = tuple(n - b.start for n, b in zip(ijk, block, strict=True))
    return cell[ijk] * ratio < heaviest[at]
