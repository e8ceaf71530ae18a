"""Footprints (box or surface?), the association cost for a continuing surface, and surface columns in the EDF."""

import numpy as np
import pytest

from core.mapping.association import explained_fraction, nearest_owner
from core.mapping.box_fit import fit_upright_box
from core.mapping.footprint import Footprint
from core.mapping.local_edf import EDFGrid, local_edf, mark_columns


def _wall(a: tuple[float, float], b: tuple[float, float], height: float = 0.8, step: float = 0.05) -> np.ndarray:
    """Points on the vertical face a→b (x-y), from 5 cm up to `height`."""
    n = int(np.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1
    t = np.linspace(0.0, 1.0, n)
    xy = np.stack([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])], axis=1)
    z = np.arange(0.05, height, step)
    return np.concatenate([np.column_stack([xy, np.full(n, h)]) for h in z])


def test_an_l_of_walls_is_not_a_box_but_a_box_seen_from_two_sides_is():
    walls = np.concatenate([_wall((0.0, 0.0), (4.0, 0.0)), _wall((0.0, 0.0), (0.0, 3.0))])
    fp = Footprint.of(walls, 0.05)
    assert fp.box_gap(fit_upright_box(walls)) > 2.5  # the box would span the corridor the walls enclose
    faces = np.concatenate([_wall((0.0, 0.0), (0.6, 0.0), 0.6), _wall((0.6, 0.0), (0.6, 0.6), 0.6)])
    fp = Footprint.of(faces, 0.05)
    assert fp.box_gap(fit_upright_box(faces)) <= 0.62  # about the unseen depth of the box itself


def test_grown_footprint_contains_points_near_the_surface_columns_only():
    walls = _wall((0.0, 0.0), (2.0, 0.0))
    grown = Footprint.of(walls, 0.05).grown(0.2)
    inside = grown.contains(np.array([[1.0, 0.15, 0.5], [1.0, -0.15, 0.9], [1.0, 0.5, 0.5], [1.0, 0.0, 1.1],
                                      [2.5, 0.0, 0.5]]))
    np.testing.assert_array_equal(inside, [True, True, False, False, False])


def test_explained_fraction_counts_points_on_the_known_surface():
    known = np.zeros(30)  # on the known part of a wall
    new = np.linspace(0.1, 1.0, 30)  # its newly seen continuation, ever farther from what is known
    assert explained_fraction(np.concatenate([known, new]), 0.1) == pytest.approx(0.5)
    assert explained_fraction(np.zeros(0), 0.1) == 0.0


def test_nearest_owner_takes_the_nearest_explaining_surface():
    d = np.array([[0.02, 0.08], [0.09, 0.01], [0.3, 0.4], [0.05, 0.5]])
    np.testing.assert_array_equal(nearest_owner(d, 0.1), [0, 1, -1, 0])


def test_surface_columns_are_solid_down_to_the_floor():
    grid = EDFGrid.around(np.zeros(2), (4.0, 4.0, 1.4), 0.1, pad_m=0.5)
    occ = grid.empty()
    top = np.column_stack([np.linspace(0.5, 1.0, 6), np.zeros(6), np.full(6, 0.6)])  # a seen top face only
    mark_columns(grid, occ, top)
    edf = local_edf(grid, occ, 1.8)
    below = np.array([[0.7, 0.0, 0.3], [0.7, 0.0, 0.05]])
    assert np.all(edf.distance(below) < 0.0)  # under the seen face is inside
    assert edf.distance(np.array([[0.7, 0.0, 0.9]]))[0] == pytest.approx(0.25, abs=0.1)
    assert edf.distance(np.array([[0.7, 0.5, 0.3]]))[0] == pytest.approx(0.45, abs=0.1)
    assert not occ[:, :, 0].any()  # the node below the floor stays free
