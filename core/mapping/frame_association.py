"""One frame's association as the object mapper applies it: which points each object was seen by, the
segments left for new objects and the objects to merge (`ObjectMapper.integrate`); the costs and the
assignment themselves are `association.py`'s."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.mapping.segmentation import Segment
from core.mapping.tracked_object import TrackedObject


@dataclass
class Observed:
    """What one frame saw of a matched object: points (N×3, world), an even sample of them and the
    sample's distances to the object (truncated at the association cap; the cost, the registration
    trigger and Delta all use them, so they are computed once)."""

    obj: TrackedObject
    points: np.ndarray
    sample: np.ndarray
    distances: np.ndarray


@dataclass
class FrameAssociation:
    """One frame's association: per object the point sets it was seen by (with the sample distances when
    a whole segment went to it, already computed for its cost), the segments left for new objects, and
    (keep, gone) pairs of objects to merge."""

    shares: dict[int, list[tuple[np.ndarray, np.ndarray | None, np.ndarray | None]]] = field(default_factory=dict)
    objects: dict[int, TrackedObject] = field(default_factory=dict)
    leftovers: list[Segment] = field(default_factory=list)
    merges: list[tuple[TrackedObject, TrackedObject]] = field(default_factory=list)

    def add(self, obj: TrackedObject, points: np.ndarray, sample: np.ndarray | None = None,
            distances: np.ndarray | None = None) -> None:
        self.objects[obj.id] = obj
        self.shares.setdefault(obj.id, []).append((points, sample, distances))

    def gone(self) -> set[int]:
        """Ids of the objects merged into others."""
        return {g.id for _, g in self.merges}

    def keepers(self) -> dict[int, TrackedObject]:
        """For each merged object's id, the surviving object it ends up in (merges may chain)."""
        into = {g.id: k for k, g in self.merges}
        for gone_id in list(into):
            keep, seen = into[gone_id], {gone_id}
            while keep.id in into and keep.id not in seen:
                seen.add(keep.id)
                keep = into[keep.id]
            into[gone_id] = keep
        return into

    def merge(self) -> None:
        """Each merged object's surface into the object it ends up in."""
        gone = {g.id: g for _, g in self.merges}
        for gone_id, keep in self.keepers().items():
            keep.absorb(gone[gone_id])

    def observed(self, n_sample: int, cap_m: float) -> list[Observed]:
        """What each surviving object was seen by; shares of merged objects go to the object that took them."""
        into = self.keepers()
        shares: dict[int, list[tuple[np.ndarray, np.ndarray | None, np.ndarray | None]]] = {}
        owners: dict[int, TrackedObject] = {}
        for oid, parts in self.shares.items():
            obj = into.get(oid, self.objects[oid])
            owners[obj.id] = obj
            shares.setdefault(obj.id, []).extend(parts if obj.id == oid else [(pts, None, None) for pts, _, _ in parts])
        out = []
        for oid, parts in shares.items():
            obj = owners[oid]
            points, sample, distances = parts[0]
            if len(parts) > 1 or sample is None or distances is None:
                points = np.concatenate([pts for pts, _, _ in parts])
                sample = points[::max(1, -(-len(points) // n_sample))]
                distances = obj.distance(sample, cap_m)
            out.append(Observed(obj, points, sample, distances))
        return out
