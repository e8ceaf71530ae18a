"""Floor removal before segmentation (docs/method.md, "Perception", step 2).

The floor is the plane z = 0 of the world (the robot's odometry frame); boxes stand on it. A point
is floor when it lies below `floor_height_m`, raised by three standard deviations of the depth noise
model (std = c · z², z the point's depth) times the ray's vertical component, so that far, noisy
floor returns do not survive as specks of clutter.
"""

from __future__ import annotations

import numpy as np


def floor_threshold(depth_m: np.ndarray, ray_dz: np.ndarray, floor_height_m: float,
                    noise_coeff_m: float) -> np.ndarray:
    """Height (m) below which a point is floor: floor_height + 3 · c · z² · |dz| per point."""
    return floor_height_m + 3.0 * noise_coeff_m * depth_m**2 * np.abs(ray_dz)


def above_floor(points: np.ndarray, threshold_m: float | np.ndarray) -> np.ndarray:
    """Mask of the points (N×3) higher than the floor threshold (scalar or per point)."""
    return points[:, 2] > threshold_m
