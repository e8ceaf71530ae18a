"""What a real depth camera does to the depth it measures (the sensor model's image part, `SensorParams`).

Applied to MuJoCo's exact planar depth in this order, each a pure function of the image and a
random generator:

1. surfaces that return nothing (`Box.dark`: black, shiny, transparent): their pixels read 0;
2. flying (mixed) pixels: a pixel on either side of a depth step larger than `jump_m` reads, with
   probability `fraction`, a depth drawn uniformly between the two sides: points hanging in free space
   behind the silhouettes of objects, as stereo and time-of-flight cameras give;
3. depth noise growing with depth squared: std = c · z² (stereo: the disparity error is constant);
4. random dropouts: a `fraction` of the pixels return nothing;
5. range: beyond the camera's range or nearer than its near limit reads 0 ("no return").
"""

from __future__ import annotations

import numpy as np

from core.params import SensorParams


def blank(depth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The image with the pixels of `mask` (surfaces that return nothing) set to 0."""
    return np.where(mask, 0.0, depth)


def flying_pixels(depth: np.ndarray, fraction: float, jump_m: float, rng: np.random.Generator) -> np.ndarray:
    """Mixed pixels at depth steps: of each horizontally or vertically neighbouring pair whose depths differ
    by more than `jump_m` (both returning), with probability `fraction` one of the two (either, at random)
    reads near + U(0, 1) · (far − near).

    The draws are made for every pair of the image, edge or not, so the generator's stream after this step
    does not depend on the scene: a change far from the view (a floor reaching further) leaves the noise of
    every other pixel as it was."""
    out = depth.copy()
    if fraction <= 0.0:
        return out
    for axis in (0, 1):
        a = depth[:-1, :] if axis == 0 else depth[:, :-1]
        b = depth[1:, :] if axis == 0 else depth[:, 1:]
        pick_u, second_u, mix_u = rng.random((3, *a.shape))
        rows, cols = np.nonzero((np.abs(a - b) > jump_m) & (a > 0.0) & (b > 0.0) & (pick_u < fraction))
        near, far = np.minimum(a[rows, cols], b[rows, cols]), np.maximum(a[rows, cols], b[rows, cols])
        mix = mix_u[rows, cols]
        second = second_u[rows, cols] < 0.5  # which pixel of the pair flies
        rows = rows + (second if axis == 0 else 0)
        cols = cols + (second if axis == 1 else 0)
        out[rows, cols] = near + mix * (far - near)
    return out


def depth_noise(depth: np.ndarray, coeff_m: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise of std coeff · z² on the returning pixels."""
    if coeff_m <= 0.0:
        return depth
    return np.where(depth > 0.0, depth + rng.standard_normal(depth.shape) * coeff_m * depth**2, 0.0)


def dropouts(depth: np.ndarray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """A random `fraction` of the pixels return nothing."""
    if fraction <= 0.0:
        return depth
    return np.where(rng.random(depth.shape) < fraction, 0.0, depth)


def within_range(depth: np.ndarray, near_m: float, range_m: float) -> np.ndarray:
    """Pixels nearer than `near_m` or beyond `range_m` read 0 (no return), as depth cameras report."""
    return np.where((depth >= near_m) & (depth <= range_m), depth, 0.0)


def sense(depth: np.ndarray, sensor: SensorParams, near_m: float, range_m: float, rng: np.random.Generator,
          no_return: np.ndarray | None = None) -> np.ndarray:
    """The depth image a real camera reports for the exact planar `depth` (steps 1–5 of the module doc).

    The range cut comes before the noise as well as after it: a far background (MuJoCo's far plane) must not
    be brought into range by noise; flying pixels between a near edge and a far background may land in range,
    as they do on real cameras."""
    d = depth if no_return is None else blank(depth, no_return)
    d = flying_pixels(d, sensor.flying_pixel_fraction, sensor.flying_pixel_jump_m, rng)
    d = within_range(d, near_m, range_m)
    d = depth_noise(d, sensor.depth_noise_m, rng)
    d = dropouts(d, sensor.dropout_fraction, rng)
    return within_range(d, near_m, range_m)
