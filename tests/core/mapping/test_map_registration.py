"""The object registration (`core/mapping/registration.py`): a planar push of a box surface is recovered, the
same inputs give the same bits (lockstep runs depend on it), and clouds too small to tell a push from noise
are not aligned."""

import numpy as np

from core.mapping.registration import MIN_POINTS, align
from core.mapping.tracked_object import TrackedObject, yaw_pose
from core.params import MappingParams


def _box_surface(half: np.ndarray, spacing_m: float = 0.02) -> np.ndarray:
    """Points on the five visible faces (all but the bottom) of a box centred at the origin."""
    axes = [np.arange(-h, h + 1e-9, spacing_m) for h in half]
    faces = []
    for a in range(3):
        u, v = [axes[i] for i in range(3) if i != a]
        U, V = np.meshgrid(u, v, indexing="ij")
        for sign in ((1.0,) if a == 2 else (-1.0, 1.0)):
            face = np.zeros((U.size, 3))
            face[:, [i for i in range(3) if i != a]] = np.c_[U.ravel(), V.ravel()]
            face[:, a] = sign * half[a]
            faces.append(face)
    return np.concatenate(faces)


def test_a_planar_push_is_recovered_and_repeats_bit_for_bit():
    box = _box_surface(np.array([0.2, 0.15, 0.3]))
    push = yaw_pose(np.radians(4.0), np.array([0.06, -0.03, 0.0]))
    rng = np.random.default_rng(1)
    seen = box[box[:, 0] < 0.1] @ push[:3, :3].T + push[:3, 3]  # a partial view of the pushed box
    seen += rng.normal(0.0, 0.003, seen.shape)
    p = MappingParams()
    first = align(seen, box, p.icp_max_correspondence_m, p.icp_max_iterations, p.icp_normal_neighbours)
    undo = np.linalg.inv(push)
    np.testing.assert_allclose(first.T[:3, 3], undo[:3, 3], atol=0.005)
    assert abs(np.arctan2(first.T[1, 0], first.T[0, 0]) + np.radians(4.0)) < np.radians(0.5)
    assert first.fitness > 0.95 and first.rmse_m < 0.01
    for _ in range(5):
        again = align(seen, box, p.icp_max_correspondence_m, p.icp_max_iterations, p.icp_normal_neighbours)
        assert np.array_equal(again.T, first.T)


def test_clouds_too_small_are_not_aligned():
    few = np.random.default_rng(2).uniform(0.0, 0.3, (MIN_POINTS - 1, 3))
    result = align(few + 0.05, _box_surface(np.array([0.2, 0.2, 0.2])), 0.35, 30, 16)
    assert np.array_equal(result.T, np.eye(4)) and result.fitness == 0.0


def test_a_refit_box_gets_its_own_solid():
    """The solid box is cached per fit: a refit (more voxels) must give the new box, never the old one."""
    p = MappingParams()
    small = _box_surface(np.array([0.2, 0.2, 0.3])) + [0.0, 0.0, 0.3]
    obj = TrackedObject(0, small, p.voxel_m, p.prior(), floor_snap_m=p.floor_snap_m)
    obj.integrate(small)
    before = obj.solid.extent.copy()
    longer = _box_surface(np.array([0.6, 0.2, 0.3])) + [0.4, 0.0, 0.3]
    for _ in range(3):
        obj.integrate(longer)
    assert obj.solid.extent[0] > before[0] + 0.5, (before, obj.solid.extent)
