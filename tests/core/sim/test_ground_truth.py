import numpy as np
import pytest

from core.scene import Box
from core.sim.ground_truth import box_signed_distance, ground_truth_edf


def test_box_signed_distance_hand_computed():
    box = Box("b", (1.0, 0.0, 0.5), (1.0, 2.0, 1.0))
    pts = np.array([[2.0, 0.0, 0.5], [1.0, 0.0, 0.5], [2.5, 2.0, 0.5], [1.0, 0.0, 2.0]])
    np.testing.assert_allclose(box_signed_distance(pts, box), [0.5, -0.5, np.hypot(1.0, 1.0), 1.0])


def test_yawed_box():
    box = Box("b", (0.0, 0.0, 0.3), (0.6, 0.6, 0.6), yaw=np.pi / 4)
    d = box_signed_distance(np.array([1.0, 0.0, 0.3]), box)
    assert d == pytest.approx(1.0 - 0.3 * np.sqrt(2))


def test_edf_grid_interpolates_exact_distance():
    boxes = [Box("a", (1.0, 0.0, 0.3)), Box("b", (-1.0, 1.0, 0.3))]
    edf = ground_truth_edf(boxes, np.zeros(2), voxel_m=0.1, cutoff_m=1.8)
    rng = np.random.default_rng(0)
    pts = rng.uniform([-1.8, -1.8, 0.1], [1.8, 1.8, 1.2], size=(500, 3))
    exact = np.minimum(np.minimum(box_signed_distance(pts, boxes[0]), box_signed_distance(pts, boxes[1])), 1.8)
    assert np.abs(edf.distance(pts) - exact).max() < 0.1
    assert edf.distance(np.array([10.0, 0.0, 0.3])) == 1.8
