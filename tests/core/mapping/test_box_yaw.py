"""Box yaw from the sides its points lie on: two seen faces of a square box (an L) give the box's yaw, not the
L's diagonal, which has the same minimum-area rectangle."""

import math

import numpy as np

from core.mapping.box_fit import fit_upright_box
from core.mapping.box_yaw import side_yaw


def _seen_corner(yaw: float, noise_m: float, seed: int = 0) -> np.ndarray:
    """x-y points on the two faces of a 0.6 m square box (yawed by `yaw`) that a camera on its −x, −y side
    sees, spread by `noise_m` along each face's normal."""
    rng = np.random.default_rng(seed)
    t = np.repeat(np.linspace(-0.3, 0.3, 25), 8)
    a = np.stack([t, -0.3 + rng.normal(0.0, noise_m, len(t))], axis=1)  # the face at y = −0.3
    b = np.stack([-0.3 + rng.normal(0.0, noise_m, len(t)), t], axis=1)  # the face at x = −0.3
    c, s = math.cos(yaw), math.sin(yaw)
    return np.concatenate([a, b]) @ np.array([[c, s], [-s, c]])


def _off(a: float, b: float) -> float:
    d = (a - b) % (math.pi / 2)
    return math.degrees(min(d, math.pi / 2 - d))


def test_two_noisy_faces_give_the_box_yaw_not_the_diagonal():
    for yaw in (0.0, 0.3, -0.6):
        for seed in range(3):
            xy = _seen_corner(yaw, 0.03, seed)
            assert _off(side_yaw(xy), yaw) < 2.0
            z = np.tile([0.1, 0.3, 0.5], len(xy) // 3 + 1)[:len(xy)]
            fit = fit_upright_box(np.column_stack([xy, z]))
            assert _off(fit.yaw, yaw) < 2.0
            assert np.all(fit.extent[:2] < 0.7)  # about the box, not a diamond round the L


def test_side_yaw_is_within_the_frame_quarter_and_zero_for_too_few_points():
    assert -math.pi / 4 <= side_yaw(_seen_corner(0.78, 0.01)) < math.pi / 4
    assert side_yaw(np.zeros((2, 2))) == 0.0
