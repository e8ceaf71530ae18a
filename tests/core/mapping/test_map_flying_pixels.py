"""The flying-pixel filter on frames rendered with the sensor model: points hanging behind silhouettes go,
the surfaces stay."""

from dataclasses import replace

import numpy as np

from core.mapping.depth_points import unproject
from core.mapping.flying_pixels import EdgeFilter, neighbourhoods, neighbourhoods_at, without_flying_pixels
from core.params import MappingParams, SensorParams
from core.scene import Box
from core.sim.ground_truth import box_signed_distance
from tests.core.mapping.rendered_views import View

BOX = Box("a", (1.8, 0.0, 0.3), yaw=0.3)
WALL = Box("wall", (3.2, 0.0, 1.0), (0.2, 6.0, 2.0))


def _off_surfaces(points: np.ndarray) -> np.ndarray:
    """Distance (m) of points to the nearest true surface: box, wall or floor."""
    d = np.minimum(np.abs(box_signed_distance(points, BOX)), np.abs(box_signed_distance(points, WALL)))
    return np.minimum(d, np.abs(points[:, 2]))


SPAN_ONLY = EdgeFilter(0.1, 0.05, 0.005, min_support=0, slope=0.01)


def test_a_step_marks_both_rims_and_no_return_takes_no_part_in_the_span():
    depth = np.full((8, 10), 2.0)
    assert not SPAN_ONLY.mixed(depth, neighbourhoods(depth, 1)).any()
    depth[:, 5:] = 3.0
    mixed = SPAN_ONLY.mixed(depth, neighbourhoods(depth, 1))
    assert np.all(mixed[:, [4, 5]]) and not mixed[:, [0, 1, 2, 3, 7, 8, 9]].any()
    depth[:, 5] = 0.0
    assert not SPAN_ONLY.mixed(depth, neighbourhoods(depth, 1))[:, 4].any()


def test_a_pixel_with_no_surface_around_it_is_mixed_even_where_its_far_side_returns_nothing():
    depth = np.full((9, 9), 2.0)
    depth[:, 5:] = 0.0  # a background beyond the range
    depth[4, 5] = 2.25  # a mixed pixel, a quarter metre behind the near side
    edges = replace(SPAN_ONLY, min_support=3)
    assert not SPAN_ONLY.mixed(depth, neighbourhoods(depth, 1))[4, 5]  # 0.25 m: inside the span limit
    mixed = edges.mixed(depth, neighbourhoods(depth, 1))
    assert mixed[4, 5] and not mixed[:, :4].any()
    assert not mixed[[0, 8], 4].any()  # a corner-like rim pixel with 3 neighbours on its surface stays


def test_scattered_pixels_get_the_neighbourhoods_of_the_strided_frame():
    depth = np.random.default_rng(0).uniform(0.0, 3.0, (12, 16))
    grid = neighbourhoods(depth, 2)
    v, u = np.mgrid[0:12:2, 0:16:2]
    np.testing.assert_array_equal(neighbourhoods_at(depth, v.ravel(), u.ravel()), grid.reshape(9, -1))


def test_flying_pixels_are_dropped_and_surfaces_kept(robot):
    params = MappingParams()
    sensor = replace(SensorParams(), dropout_fraction=0.0)
    view = View(robot, (BOX, WALL), cameras=("base",), sensor=sensor, seed=4)
    exact = View(robot, (BOX, WALL), cameras=("base",)).frame_set()[0]
    frame = view.frame_set()[0]
    raw = unproject(frame.depth, frame.K, frame.T_world_camera, params.pixel_stride)
    kept_depth = without_flying_pixels(frame.depth, params.pixel_stride, EdgeFilter.of(params))
    kept = unproject(kept_depth, frame.K, frame.T_world_camera, params.pixel_stride)
    z = np.linalg.norm(raw - frame.T_world_camera[:3, 3], axis=1)
    far_off = _off_surfaces(raw) > 0.1 + 3 * params.depth_noise_coeff_m * z**2  # beyond the noise: flying
    assert far_off.sum() > 15
    off = _off_surfaces(kept)
    z_kept = np.linalg.norm(kept - frame.T_world_camera[:3, 3], axis=1)
    assert np.sum(off > 0.1 + 3 * params.depth_noise_coeff_m * z_kept**2) <= 0.1 * far_off.sum()
    # and all but the rims of the silhouettes stay: at least 90 % of the exact image's points
    n_exact = len(unproject(exact.depth, exact.K, exact.T_world_camera, params.pixel_stride))
    assert len(kept) >= 0.9 * n_exact
    view.close()
