"""Probes under the surface of a floor-standing object: where free space, if seen, shows the surface is not there.

An object standing on the floor is solid under its surface: the EDF fills the column under every surface voxel
of an object that is not box-like down to the floor (`local_edf.column_field`), and a box-like object is its box
completed down to the floor (`completion.py`). Right under a surface voxel lies the object: its body under a
top, more of the same face under a side voxel. A ray through that point meets the object first (a face in
front of it, or the face it lies on) and returns no farther than it: it is hit or occluded, never seen through.

Old surface left by a moved box breaks that: the box was pushed along the face the camera sees, the
registration could not explain the move from one face (`registration.py` solves only the directions an
observation constrains), and the new place was fused into the object beside the old one. The old faces are
seen through and carved where something returns behind them, but a ray that returns nothing is no evidence
(`visibility.py`): the old top, seen from the box's side at the base camera's height (below the top), and the
upper part of an old side face, seen level, have nothing but the sky or empty space beyond the range behind
them, and the hand camera standing over them does not have them in its image. The space under them is in
plain view all the while: the rays to it go on down to the floor, or to the new face. (Anchored picks, localization
off: seed 1, lap 3, box_a moved 0.38 m, a 0.2 m strip of its old top stayed for the 40 s the robot stood at the
stance, the object mapped 0.93 m long; seed 4, lap 2, box_a moved 0.40 m, the upper half of its old −x face
stayed, 1.01 m.)

So a voxel's probe, `depth_m` under it, seen through counts as the voxel seen through. Only objects whose fitted
box reaches the floor (a shelf at hand height is free below). The probes are classified with the floor's returns
as returns (`FrameView.classify`, `floor_is_free` False; elsewhere they count as no return): a probe at or below
the floor is hit or occluded by it, never seen through, and one above it is seen through where the ray goes on
to the floor beyond it. Where a part
overhangs (a box pushed off the one it stands on), the bottom `depth_m` of its faces and its underside have free
space under them and go; the EDF still holds them, under what remains of the part (the fitted box's solid, or
the columns under the surface).
"""

from __future__ import annotations

import numpy as np

from core.mapping.box_fit import BoxFit


def column_probes(points: np.ndarray, fit: BoxFit, floor_z: float, depth_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the voxels among `points` (V×3, the object frame, z up) that are probed and their probes (P×3,
    the same frame): each `depth_m` straight under its voxel. None if the fit does not reach `floor_z`."""
    if fit.centre[2] - fit.half[2] > floor_z + 1e-6:
        return np.zeros(0, dtype=int), np.zeros((0, 3))
    return np.arange(len(points)), points - np.array([0.0, 0.0, depth_m])
