"""One frame's association bookkeeping: chained merges end in one surviving object that gets the surfaces and
the observations of the objects merged into it; the Hungarian assignment keeps only pairs under the gate."""

import numpy as np

from core.mapping.association import assign
from core.mapping.frame_association import FrameAssociation
from core.mapping.tracked_object import TrackedObject
from core.params import MappingParams


def _slab(object_id: int, x0: float, x1: float) -> TrackedObject:
    """An object whose surface is a vertical face from x0 to x1 at y = 0 (5 cm points)."""
    x, z = np.meshgrid(np.arange(x0, x1, 0.05), np.arange(0.05, 0.5, 0.05), indexing="ij")
    points = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    return TrackedObject(object_id, points, 0.05, MappingParams().prior(), floor_snap_m=10.0)


def test_chained_merges_end_in_the_surviving_object():
    big, middle, small = _slab(1, 0.0, 2.0), _slab(2, 1.5, 2.5), _slab(3, 2.2, 2.4)
    out = FrameAssociation()
    seen = np.array([[2.3, 0.0, 0.2], [2.25, 0.0, 0.3]])
    out.add(small, seen)
    out.add(middle, seen + [0.1, 0.0, 0.0])
    out.merges = [(middle, small), (big, middle)]  # the later merge takes the earlier one's keeper along
    assert {k: v.id for k, v in out.keepers().items()} == {3: 1, 2: 1}
    out.merge()
    assert big.world_points[:, 0].max() > 2.4  # the survivor took the merged surfaces beyond its own
    (observed,) = out.observed(n_sample=128, cap_m=0.5)
    assert observed.obj is big and len(observed.points) == 4
    np.testing.assert_allclose(observed.distances, big.distance(observed.sample, 0.5))
    assert out.gone() == {2, 3}


def test_assignment_keeps_pairs_under_the_gate_only():
    C = np.array([[0.05, 0.4], [0.3, np.inf], [np.inf, 0.1]])
    result = assign(C, gate_m=0.25)
    assert set(result.pairs) == {(0, 0), (2, 1)}
    assert result.unmatched_segments == (1,) and result.unmatched_objects == ()
