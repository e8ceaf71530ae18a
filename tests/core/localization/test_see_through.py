"""Objects a frame looks through (`core/localization/see_through.py`) on exact synthetic frames: a pose slipped toward a
wall looks through it by the slip; the right pose, a box's silhouette under a small pose error, a box hidden behind
another and pixels that returned nothing look through nothing."""

from __future__ import annotations

import numpy as np
import pytest

from core.localization import se2
from core.localization.see_through import seen_through
from tests.core.localization.synthetic import FLOOR, Rect, box, camera_pose, render, surface

WALL = Rect(0, 2.2, (-3.0, 0.0), (3.0, 1.5), 1)
"""A wall 2.2 m ahead of a camera at the origin facing +x."""


def _through(rects: list[Rect], mapped: list[Rect], error: np.ndarray, beyond_m: float = 0.1) -> dict[int, float]:
    """What a frame rendered at the true pose (0, 0, 0) of `rects` looks through of the `mapped` surfaces when posed
    `error` (x, y, yaw) off."""
    truth = camera_pose(0.0, 0.0, 0.0)
    frame = render(rects, truth)
    ref = surface(mapped)
    return seen_through(ref.points, ref.object_ids, frame, se2.to_matrix(error) @ truth, beyond_m, 3.0, 20, 0.5)


def test_the_right_pose_looks_through_nothing():
    assert _through([FLOOR, WALL], [WALL], np.zeros(3)) == {}


@pytest.mark.parametrize("slip_m", [0.3, 0.5])
def test_a_pose_slipped_toward_a_wall_looks_through_it_by_the_slip(slip_m):
    """By the slip along the optical axis (pitched 15° down), less the depth the wall gains across the window."""
    through = _through([FLOOR, WALL], [WALL], np.array([slip_m, 0.0, 0.0]))
    assert set(through) == {1}
    assert slip_m - 0.06 < through[1] <= slip_m


def test_a_pose_slipped_away_from_a_wall_sees_it_in_front_and_looks_through_nothing():
    """The points land before the mapped wall: for the residuals to judge, not this check."""
    assert _through([FLOOR, WALL], [WALL], np.array([-0.5, 0.0, 0.0])) == {}


@pytest.mark.parametrize("error_m", [0.03, 0.05])
def test_a_box_silhouette_under_a_small_pose_error_is_not_looked_through(error_m):
    """A box 1 m ahead at the image's side, the pose a few cm off sideways: most of its points in view lie by its
    edges, which project a few pixels past the box (judged at the pixel alone, 0.14 / 0.25 m "looked through")."""
    cube = box((1.0, 0.5), 0.6, 3)
    assert _through([FLOOR, *cube], cube, np.array([0.0, error_m, 0.0])) == {}


def test_a_box_hidden_behind_another_says_nothing():
    near, far = box((1.0, 0.0), 0.6, 3), box((2.2, 0.0), 0.4, 4)
    assert _through([FLOOR, *near, *far], [*near, *far], np.zeros(3)) == {}


def test_pixels_that_returned_nothing_do_not_look_through():
    """A mapped wall the frame returned nothing for (dark, dropouts, past the range): unknown, not looked through."""
    truth = camera_pose(0.0, 0.0, 0.0)
    frame = render([FLOOR, WALL], truth)
    blank = type(frame)(frame.t, frame.camera, np.zeros_like(frame.depth), frame.K, frame.T_world_camera, frame.range_m)
    ref = surface([WALL])
    assert seen_through(ref.points, ref.object_ids, blank, truth, 0.1, 3.0, 20, 0.5) == {}
