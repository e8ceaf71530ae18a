"""The noise shell of a face seen from afar leaves the surface columns; a face only ever seen from afar stays."""

import numpy as np

from core.mapping.local_edf import EDFGrid, column_field
from core.mapping.noise_shell import outweighed


def _wall(x: float, n: int = 40) -> np.ndarray:
    """Points on the plane x = `x`, y in [−1, 1], z in [0.1, 0.7]."""
    rng = np.random.default_rng(0)
    return np.column_stack([np.full(n * 4, x), rng.uniform(-1.0, 1.0, n * 4), rng.uniform(0.1, 0.7, n * 4)])


def test_light_points_in_front_of_a_heavy_face_are_outweighed_and_a_light_face_alone_is_not():
    grid = EDFGrid.around(np.zeros(2), (4.0, 4.0, 1.4), 0.1, pad_m=0.5)
    face, shell = _wall(1.0), _wall(0.93, 10)  # the shell: far returns 7 cm in front of the face
    points = np.concatenate([face, shell])
    weights = np.concatenate([np.ones(len(face)), np.full(len(shell), 1 / 81)])  # near (1 m) and far (3 m) views
    out = outweighed(grid.origin, grid.voxel, grid.shape, points, weights, 40.0)
    assert not out[:len(face)].any() and out[len(face):].mean() > 0.9
    assert not outweighed(grid.origin, grid.voxel, grid.shape, shell, np.full(len(shell), 1 / 81), 40.0).any()


def test_the_columns_read_the_face_not_its_noise_shell():
    grid = EDFGrid.around(np.zeros(2), (4.0, 4.0, 1.4), 0.1, pad_m=0.5)
    face, shell = _wall(1.0), _wall(0.93, 10)
    points = np.concatenate([face, shell])
    weights = np.concatenate([np.ones(len(face)), np.full(len(shell), 1 / 81)])
    nodes = np.array([0.5, 0.0, 0.4]) - grid.window_origin
    i, j, k = np.rint(nodes / grid.voxel).astype(int)
    kept = column_field(grid, points, 1.8, weights, shell_ratio=40.0)[i, j, k]
    every = column_field(grid, points, 1.8, weights)[i, j, k]
    assert abs(kept - 0.5) < 0.01 and every < 0.45  # 0.5 m from the face; the shell read 7 cm nearer
