"""Angles: wrapping a heading (or a heading difference) to [-π, π), for floats and numpy arrays alike."""

from __future__ import annotations

import math
from typing import overload

import numpy as np


@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: np.ndarray) -> np.ndarray: ...
def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """`angle` (rad) in [-π, π): the shortest signed turn when `angle` is a difference of headings."""
    return (angle + math.pi) % (2 * math.pi) - math.pi
