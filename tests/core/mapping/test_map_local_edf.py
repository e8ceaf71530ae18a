"""Local EDF (9a–9b, signed): against the analytic signed distance to a box, gradients, window edges."""

import numpy as np
import pytest
from scipy import ndimage

from core.mapping.local_edf import EDFGrid, depth_inside, local_edf, mark_boxes, mark_points, signed_distance
from core.scene import Box
from core.sim.ground_truth import box_signed_distance

WINDOW = (4.0, 4.0, 1.4)


def _edf_of_box(box: Box, centre=(0.0, 0.0), voxel: float = 0.1):
    grid = EDFGrid.around(np.array(centre), WINDOW, voxel, pad_m=0.5)
    occ = grid.empty()
    mark_boxes(grid, occ, [(box.pose(), np.array(box.size))])
    return local_edf(grid, occ, cutoff=1.8)


def _grid_points(edf):
    axes = [edf.origin[i] + edf.voxel * np.arange(edf.values.shape[i]) for i in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)


@pytest.mark.parametrize("yaw", [0.0, 0.4])
def test_edf_within_one_voxel_of_the_analytic_distance(yaw):
    box = Box("b", (1.03, 0.27, 0.3), (0.6, 0.6, 0.6), yaw)
    edf = _edf_of_box(box)
    assert edf.values.shape == (41, 41, 15)
    truth = np.minimum(box_signed_distance(_grid_points(edf), box), 1.8)
    assert np.max(np.abs(edf.values - truth)) <= edf.voxel
    # between nodes, trilinear interpolation keeps the bound
    rng = np.random.default_rng(0)
    p = rng.uniform(edf.origin, edf.upper, size=(5000, 3))
    err = np.abs(edf.distance(p) - np.minimum(box_signed_distance(p, box), 1.8))
    assert np.max(err) <= edf.voxel
    # signed: negative inside the box, positive outside
    assert edf.distance(np.array(box.position)) < -0.2
    assert edf.distance(np.array([-1.0, -1.0, 0.5])) > 0.0


@pytest.mark.parametrize("offset", [0.0, 0.013, 0.031, 0.05, 0.077])
def test_a_box_fitted_to_one_face_stays_in_the_field_wherever_the_nodes_fall(offset):
    """A long row seen only from the side is fitted as a slab of no thickness; it must not fall between
    node rows (it did: the arm touched a shelf the field said was 1.8 m away)."""
    face = Box("row", (0.0, 1.0 + offset, 0.4), (3.0, 0.0, 0.8), 0.0)
    edf = _edf_of_box(face, centre=(0.0, 0.0))
    for y in (0.7, 0.8, 1.3):
        p = np.array([0.2, y + offset, 0.4])
        assert abs(edf.distance(p) - abs(y - 1.0)) <= edf.voxel + 1e-9
    assert edf.distance(np.array([0.2, 1.0 + offset, 0.4])) <= 0.0


def test_gradient_is_unit_and_points_away_from_the_box():
    box = Box("b", (1.0, 0.3, 0.3), (0.6, 0.6, 0.6), 0.3)
    edf = _edf_of_box(box)
    rng = np.random.default_rng(1)
    p = rng.uniform(edf.origin, edf.upper, size=(20000, 3))
    d = box_signed_distance(p, box)
    away = p[(d > 0.3) & (d < 1.2)]
    g = edf.gradient(away)
    norm = np.linalg.norm(g, axis=1)
    assert np.median(norm) == pytest.approx(1.0, abs=0.05)
    assert np.all((norm > 0.75) & (norm < 1.25))
    # the analytic gradient (finite differences) of the true distance
    h = 1e-4
    true_g = np.stack([(box_signed_distance(away + h * e, box) - box_signed_distance(away - h * e, box)) / (2 * h)
                       for e in np.eye(3)], axis=1)
    cos = np.sum(g * true_g, axis=1) / norm
    assert np.min(cos) > 0.8 and np.median(cos) > 0.98
    # inside the box the gradient points out too (towards larger distance)
    inside = p[d < -0.15]
    gi = edf.gradient(inside)
    true_gi = np.stack([(box_signed_distance(inside + h * e, box) - box_signed_distance(inside - h * e, box))
                        / (2 * h) for e in np.eye(3)], axis=1)
    dots = np.sum(gi * true_gi, axis=1)
    assert np.all(dots > -0.05)  # never deeper in
    assert np.mean(dots) > 0.4


def test_cutoff_outside_the_window_and_with_nothing_mapped():
    box = Box("b", (1.0, 0.3, 0.3))
    edf = _edf_of_box(box)
    far = np.array([[10.0, 10.0, 0.5], [0.0, 0.0, 5.0]])
    np.testing.assert_allclose(edf.distance(far), 1.8)
    np.testing.assert_allclose(edf.gradient(far), 0.0)
    grid = EDFGrid.around(np.zeros(2), WINDOW, 0.1)
    empty = local_edf(grid, grid.empty(), 1.8)
    np.testing.assert_allclose(empty.values, 1.8)


def test_a_box_just_outside_the_window_still_shapes_its_edge():
    box = Box("b", (2.3, 0.0, 0.3))  # its near face at x = 2.0, the window's edge
    edf = _edf_of_box(box)
    p = np.array([[1.5, 0.0, 0.3]])
    assert edf.distance(p)[0] == pytest.approx(0.5, abs=0.1)


def test_inside_depth_per_region_equals_the_full_transform():
    rng = np.random.default_rng(2)
    occ = ndimage.binary_dilation(rng.random((30, 25, 12)) > 0.97, iterations=2)
    np.testing.assert_allclose(depth_inside(occ), ndimage.distance_transform_edt(occ))
    assert signed_distance(occ, 0.1, 1.8).min() < 0.0


def test_points_mark_their_nearest_node():
    grid = EDFGrid.around(np.zeros(2), WINDOW, 0.1)
    occ = grid.empty()
    mark_points(grid, occ, np.array([[0.02, 0.01, 0.51], [50.0, 0.0, 0.0]]))
    idx = np.argwhere(occ)
    np.testing.assert_allclose(grid.origin + idx[0] * 0.1, [0.0, 0.0, 0.5], atol=1e-9)
    assert len(idx) == 1
    assert grid.window_origin[2] == 0.0 and grid.origin[2] == pytest.approx(-0.1)
