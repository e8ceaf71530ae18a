"""LocalEDF's trilinear interpolant: exact on affine fields, its gradient is the interpolant's own, the field is
`cutoff` outside the grid, and the one-lookup `distance_and_gradient` equals the two separate queries."""

import numpy as np

from core.types import LocalEDF


def _affine_edf(shape: tuple[int, int, int] = (7, 5, 4)) -> tuple[LocalEDF, np.ndarray, float]:
    origin, voxel = np.array([-0.3, 0.2, 0.0]), 0.1
    slope = np.array([0.7, -0.4, 0.25])
    axes = [origin[i] + voxel * np.arange(n) for i, n in enumerate(shape)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    return LocalEDF(origin=origin, voxel=voxel, values=grid @ slope + 0.1, cutoff=2.0), slope, 0.1


def test_exact_on_an_affine_field() -> None:
    edf, slope, offset = _affine_edf()
    rng = np.random.default_rng(0)
    p = edf.origin + rng.uniform(0.0, 1.0, (4, 6, 3)) * (edf.upper - edf.origin)
    d, g = edf.distance_and_gradient(p)
    np.testing.assert_allclose(d, p @ slope + offset, atol=1e-12)
    np.testing.assert_allclose(g, np.broadcast_to(slope, g.shape), atol=1e-12)
    np.testing.assert_array_equal(d, edf.distance(p))
    np.testing.assert_array_equal(g, edf.gradient(p))


def test_gradient_is_the_interpolants_derivative() -> None:
    rng = np.random.default_rng(1)
    edf = LocalEDF(origin=np.zeros(3), voxel=0.1, values=rng.uniform(-0.2, 1.0, (6, 7, 5)), cutoff=1.0)
    p = rng.uniform(0.05, 0.35, (50, 3))
    g = edf.gradient(p)
    eps = 1e-6
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = eps
        fd = (edf.distance(p + step) - edf.distance(p - step)) / (2 * eps)
        np.testing.assert_allclose(g[:, axis], fd, atol=1e-5)


def test_outside_the_grid_is_cutoff_and_flat() -> None:
    edf, _, _ = _affine_edf()
    far = np.array([[5.0, 0.0, 0.0], [0.0, -4.0, 0.2], [0.0, 0.4, -1.0]])
    d, g = edf.distance_and_gradient(far)
    np.testing.assert_array_equal(d, edf.cutoff)
    np.testing.assert_array_equal(g, 0.0)
    assert edf.distance(far[0]).shape == ()  # a single point gives a scalar
