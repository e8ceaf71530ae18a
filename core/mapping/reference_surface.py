"""The narrow view of the map that localization registers against (`ReferenceSurface`): the surfaces of the
objects POCD trusts (E[v] high, seen often), or a voxel map's occupied cells; never the map itself."""

from __future__ import annotations

import numpy as np

from core.types import ObjectMapSnapshot, ReferenceSurface

UNLABELLED = -1
"""Object id of surface points that belong to no tracked object (a voxel map's cells)."""


def trusted_surface(snapshot: ObjectMapSnapshot, min_consistency: float, min_observations: int) -> ReferenceSurface:
    """Surface points of every live object with E[v] ≥ min_consistency seen at least min_observations times, and
    the ids merged into one of them."""
    trusted = [o for o in snapshot.objects
               if o.consistency >= min_consistency and o.observations >= min_observations and len(o.points)]
    if not trusted:
        return ReferenceSurface(snapshot.t, np.zeros((0, 3)), np.zeros(0, int))
    points = np.vstack([o.points for o in trusted])
    ids = np.concatenate([np.full(len(o.points), o.id, int) for o in trusted])
    kept = {o.id for o in trusted}
    return ReferenceSurface(snapshot.t, points, ids, {g: k for g, k in snapshot.merged_into.items() if k in kept})


def occupied_surface(t: float, occupied: np.ndarray) -> ReferenceSurface:
    """A map without objects (the voxel baseline): its occupied cells, unlabelled."""
    occupied = np.asarray(occupied, float).reshape(-1, 3)
    return ReferenceSurface(t, occupied, np.full(len(occupied), UNLABELLED, int))
