"""Data association of segments to mapped objects (docs/method.md, "Perception", step 4).

The cost of segment j for object i is the mean over the segment's points of their distance to the
object's surface (its submap EDF M_i, or its box faces), each distance truncated at `cap_m`: zero
when the segment lies on the known surface, about the displacement when the object was pushed a
little, `cap_m` when they are unrelated. Only objects whose bounding box, grown by the gate, overlaps
the segment's are costed (the rest are infinite), so the work grows with the objects near what is
seen. The optimal one-to-one assignment is scipy's `linear_sum_assignment`; pairs above `gate_m` are
rejected.

A segment is not always one object's: touching objects are one segment, and a segment may continue a
known surface far beyond it (the next metres of a wall the robot drives along). Objects explaining a
part of a segment (points within `explain_m` of their surface: `explained_fraction`) get those points,
each point going to the nearest surface (`nearest_owner`); the object mapper gives the unexplained
rest to the segment's match or, lacking one, to the object explaining most of it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

_UNREACHABLE = 1e6


@dataclass(frozen=True)
class Assignment:
    """Matched (segment, object) index pairs with their costs; the unmatched segments and objects."""

    pairs: tuple[tuple[int, int], ...]
    costs: tuple[float, ...]
    unmatched_segments: tuple[int, ...]
    unmatched_objects: tuple[int, ...]


def overlaps(seg_lo: np.ndarray, seg_hi: np.ndarray, obj_lo: np.ndarray, obj_hi: np.ndarray,
             grow: float) -> np.ndarray:
    """(S×O) mask: does segment j's bounding box overlap object i's, grown by `grow` on every side?"""
    a = np.all(seg_lo[:, None, :] <= obj_hi[None, :, :] + grow, axis=2)
    b = np.all(obj_lo[None, :, :] - grow <= seg_hi[:, None, :], axis=2)
    return a & b


def truncated_mean_distance(distances: np.ndarray, cap_m: float) -> float:
    """The association cost: mean of per-point surface distances, each truncated at `cap_m`."""
    return float(np.mean(np.minimum(distances, cap_m))) if len(distances) else cap_m


def explained_fraction(distances: np.ndarray, explain_m: float) -> float:
    """Fraction of a segment's points within `explain_m` of an object's surface."""
    return float(np.mean(distances < explain_m)) if len(distances) else 0.0


def nearest_owner(distances: np.ndarray, explain_m: float) -> np.ndarray:
    """Per point, the column (object) of the nearest surface among those within `explain_m`, or −1.

    `distances` is N points × K objects."""
    best = np.argmin(distances, axis=1)
    near = distances[np.arange(len(distances)), best] < explain_m
    return np.where(near, best, -1)


def cost_matrix(candidates: np.ndarray, cost: Callable[[int, int], float]) -> np.ndarray:
    """Costs (S×O) of the candidate pairs, infinite elsewhere (no distances computed there)."""
    C = np.full(candidates.shape, np.inf)
    for j, i in zip(*np.nonzero(candidates), strict=True):
        C[j, i] = cost(int(j), int(i))
    return C


def assign(C: np.ndarray, gate_m: float) -> Assignment:
    """Optimal one-to-one assignment on costs C (segments × objects), pairs with cost < gate_m kept."""
    n_seg, n_obj = C.shape
    pairs: list[tuple[int, int]] = []
    costs: list[float] = []
    if n_seg and n_obj:
        finite = np.where(np.isfinite(C), C, _UNREACHABLE)
        rows, cols = linear_sum_assignment(finite)
        for j, i in zip(rows, cols, strict=True):
            if C[j, i] < gate_m:
                pairs.append((int(j), int(i)))
                costs.append(float(C[j, i]))
    seg_done = {j for j, _ in pairs}
    obj_done = {i for _, i in pairs}
    return Assignment(tuple(pairs), tuple(costs), tuple(j for j in range(n_seg) if j not in seg_done),
                      tuple(i for i in range(n_obj) if i not in obj_done))
