"""Frozen surfaces: a trusted object's surface stays where it was first trusted while the map re-places it,
grows only by newly seen parts, and leaves when the map drops it or localization finds it disagreeing."""

from __future__ import annotations

import numpy as np

from core.localization.frozen_surfaces import FrozenSurfaces
from core.types import ReferenceSurface


def _wall(x0: float, x1: float, shift_y: float = 0.0) -> np.ndarray:
    x, z = np.meshgrid(np.arange(x0, x1, 0.05), np.arange(0.0, 0.8, 0.05))
    return np.column_stack([x.ravel(), np.full(x.size, 1.3 + shift_y), z.ravel()])


def _surface(t: float, parts: dict[int, np.ndarray]) -> ReferenceSurface:
    ids = np.concatenate([np.full(len(p), i) for i, p in parts.items()])
    return ReferenceSurface(t, np.vstack(list(parts.values())), ids.astype(int))


def test_a_trusted_surface_stays_where_it_was_frozen_when_the_map_re_places_it():
    frozen = FrozenSurfaces(freeze_sigma_m=0.05, grow_m=0.1)
    first = frozen.update(_surface(1.0, {3: _wall(0.0, 2.0)}), 0.01)
    assert np.allclose(first.points, _wall(0.0, 2.0)) and set(first.object_ids) == {3}
    # the map has since re-placed the object 6 cm off (following a drifted pose): the reference does not follow
    later = frozen.update(_surface(3.0, {3: _wall(0.0, 2.0, shift_y=0.06)}), 0.02)
    assert np.allclose(later.points, _wall(0.0, 2.0))


def test_a_frozen_surface_grows_only_by_newly_seen_parts():
    frozen = FrozenSurfaces(freeze_sigma_m=0.05, grow_m=0.1)
    frozen.update(_surface(1.0, {3: _wall(0.0, 2.0)}), 0.01)
    grown = frozen.update(_surface(3.0, {3: _wall(0.0, 4.0, shift_y=0.03)}), 0.02)
    old = grown.points[:, 0] < 2.0 - 1e-9
    assert np.allclose(grown.points[old], _wall(0.0, 2.0))  # the known part: still where it was frozen
    new = grown.points[~old]
    assert len(new) and np.all(new[:, 0] > 2.05) and np.allclose(new[:, 1], 1.33)  # only what lies beyond 0.1 m


def test_nothing_is_frozen_while_the_pose_is_uncertain():
    frozen = FrozenSurfaces(freeze_sigma_m=0.05, grow_m=0.1)
    assert len(frozen.update(_surface(1.0, {3: _wall(0.0, 2.0)}), 0.08).points) == 0
    assert len(frozen.update(_surface(3.0, {3: _wall(0.0, 2.0)}), 0.03).points) > 0


def test_objects_the_map_drops_or_that_disagree_leave_and_are_frozen_again_from_the_map():
    frozen = FrozenSurfaces(freeze_sigma_m=0.05, grow_m=0.1)
    frozen.update(_surface(1.0, {3: _wall(0.0, 2.0), 4: _wall(3.0, 4.0)}), 0.01)
    after_drop = frozen.update(_surface(3.0, {3: _wall(0.0, 2.0)}), 0.01)
    assert set(after_drop.object_ids) == {3}
    version = frozen.version
    frozen.forget([3])
    assert len(frozen.surface.points) == 0 and frozen.version > version
    # excluded (disagreeing lately): not frozen again yet; then frozen where the map has it now
    assert len(frozen.update(_surface(5.0, {3: _wall(0.0, 2.0, 0.3)}), 0.01, excluded=[3]).points) == 0
    again = frozen.update(_surface(7.0, {3: _wall(0.0, 2.0, 0.3)}), 0.01)
    assert np.allclose(again.points, _wall(0.0, 2.0, 0.3))
