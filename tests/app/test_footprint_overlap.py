"""Footprint overlap of two boxes seen from above (separating axes)."""

import math

import numpy as np
import pytest

from app.footprint_overlap import overlap_depth

CUBE = np.array([0.6, 0.6, 0.6])


def test_touching_boxes_do_not_overlap_and_shifted_ones_overlap_by_the_lesser_side():
    assert overlap_depth(np.zeros(3), 0.0, CUBE, np.array([0.6, 0.0, 0.3]), 0.0, CUBE) == pytest.approx(0.0)
    # the bench's seed 3: 0.24 and 0.41 m apart along the axes: 0.19 m deep along y
    assert overlap_depth(np.zeros(3), 0.0, CUBE, np.array([0.24, -0.41, 0.3]), 0.0, CUBE) == pytest.approx(0.19)
    assert overlap_depth(np.zeros(3), 0.0, CUBE, np.array([1.0, 1.0, 0.3]), 0.0, CUBE) < 0


def test_a_turned_box_is_judged_on_its_own_axes_too():
    """A box turned 45° beside a corner: the corner's diagonal reaches 0.42 m, so 0.7 m apart along x the two
    overlap (0.3 + 0.42 > 0.7), along the diagonal of both they do not."""
    turned = math.pi / 4
    assert overlap_depth(np.zeros(3), 0.0, CUBE, np.array([0.7, 0.0, 0.3]), turned, CUBE) == pytest.approx(
        0.3 + 0.3 * math.sqrt(2) - 0.7)
    assert overlap_depth(np.zeros(3), 0.0, CUBE, np.array([0.6, 0.6, 0.3]), turned, CUBE) < 0
