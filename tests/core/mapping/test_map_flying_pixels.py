"""The flying-pixel filter on frames rendered with the sensor model: points hanging behind silhouettes go,
the surfaces stay."""

from dataclasses import replace

import numpy as np

from core.mapping.depth_points import unproject
from core.mapping.flying_pixels import depth_span, without_flying_pixels
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


def test_span_of_a_flat_image_is_zero_and_of_a_step_is_the_step():
    depth = np.full((8, 10), 2.0)
    assert np.all(depth_span(depth, 2) == 0.0)
    depth[:, 5:] = 3.0
    span = depth_span(depth, 1)
    assert np.all(span[:, [4, 5]] == 1.0) and np.all(span[:, [0, 1, 2, 3, 7, 8, 9]] == 0.0)
    depth[:, 5] = 0.0  # no return takes no part
    assert np.all(depth_span(depth, 1)[:, 4] == 0.0)


def test_flying_pixels_are_dropped_and_surfaces_kept(robot):
    params = MappingParams()
    sensor = replace(SensorParams(), dropout_fraction=0.0)
    view = View(robot, (BOX, WALL), cameras=("base",), sensor=sensor, seed=4)
    exact = View(robot, (BOX, WALL), cameras=("base",)).frame_set()[0]
    frame = view.frame_set()[0]
    raw = unproject(frame.depth, frame.K, frame.T_world_camera, params.pixel_stride)
    kept_depth = without_flying_pixels(frame.depth, params.pixel_stride, params.flying_pixel_jump_m,
                                       params.flying_pixel_jump_per_m, params.depth_noise_coeff_m)
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
