"""What the map offers localization: the surfaces of the objects it trusts, and the ids it merged into them (a
keyframe labelled with a merged id still shows a trusted surface); nothing of an object it does not trust."""

import numpy as np

from core.mapping.reference_surface import trusted_surface
from core.types import MappedObject, ObjectMapSnapshot, Posterior


def _object(object_id: int, alpha: float, observations: int = 10) -> MappedObject:
    pts = np.full((4, 3), float(object_id))
    return MappedObject(object_id, np.eye(4), np.ones(3), pts, Posterior(0.0, 0.1, alpha, 1.0),
                        observations=observations)


def test_the_trusted_objects_surfaces_and_the_ids_merged_into_them():
    trusted, doubted, young = _object(1, 19.0), _object(2, 1.0), _object(3, 19.0, observations=1)
    snap = ObjectMapSnapshot(5.0, (trusted, doubted, young), removed_ids=(7, 8, 9), merged_into={7: 1, 8: 2, 9: 3})
    surface = trusted_surface(snap, min_consistency=0.9, min_observations=3)
    assert set(surface.object_ids.tolist()) == {1} and len(surface.points) == 4
    assert surface.merged_into == {7: 1}, "merged into an object not trusted now: not offered"


def test_nothing_trusted_offers_nothing():
    snap = ObjectMapSnapshot(5.0, (_object(2, 1.0),), removed_ids=(7,), merged_into={7: 2})
    surface = trusted_surface(snap, min_consistency=0.9, min_observations=3)
    assert len(surface.points) == 0 and surface.merged_into == {}
