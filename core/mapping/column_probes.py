"""Probes under the top of a floor-standing object: where free space, if seen, shows its top is not there.

An object standing on the floor is solid under its top: the EDF fills the column under every surface voxel of
an object that is not box-like down to the floor (`local_edf.column_field`), and a box-like object is its box
completed down to the floor (`completion.py`). So no ray can pass through the column right under a top
surface voxel of such an object: it would have to enter the object through a face first, and return nearer.

A top left behind by a moved box breaks that: the box was pushed along the face the camera sees, the
registration could not explain the move from one face (`registration.py` solves only the directions an
observation constrains), and the new place was fused into the object beside the old one. The old side faces
are seen through and carved, but the old top often is not: seen from the box's side at the base camera's
height (below the top), the rays through it rise past the new box into nothing within the range, and a ray
that returns nothing is no evidence (`visibility.py`); the hand camera standing over it does not have it in its
image. The space under it is in plain view all the while: the floor and the new face behind it return depth.
(Anchored picks, seed 1, lap 3: box_a moved 0.38 m along −y, a 0.2 m strip of its old top stayed for the
40 s the robot stood at the stance, and the object was mapped 0.93 m long.)

So a top voxel's probe, `depth_m` under it, seen through counts as the voxel seen through. Only the voxels
within `band_m` of the top of the object's fitted box are probed (a floating part's underside, or an offset
stack's overhang, lower down, is not a top: free space under it is where it should be), only objects whose
fitted box reaches the floor (a shelf at hand height is free below), and only probes at least `depth_m` above
the floor (a low object's probe would sit at the floor, whose returns count as no return).
"""

from __future__ import annotations

import numpy as np

from core.mapping.box_fit import BoxFit


def top_probes(points: np.ndarray, fit: BoxFit, floor_z: float, depth_m: float,
               band_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the top voxels among `points` (V×3, the object frame, z up) and their probes (P×3, the same
    frame): each `depth_m` straight under its voxel. None if the fit does not reach `floor_z` or its top is
    lower than two `depth_m` above it."""
    top = fit.centre[2] + fit.half[2]
    bottom = fit.centre[2] - fit.half[2]
    if bottom > floor_z + 1e-6 or top - floor_z < 2.0 * depth_m:
        return np.zeros(0, dtype=int), np.zeros((0, 3))
    index = np.nonzero(points[:, 2] >= top - band_m)[0]
    probes = points[index] - np.array([0.0, 0.0, depth_m])
    return index, probes
