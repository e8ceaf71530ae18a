"""Colour maps of the studio: consistency E[v] (green → red) and distance (red near → blue far)."""

from __future__ import annotations

from typing import Literal

import numpy as np

NamedColour = Literal["red", "green", "yellow", "blue"]
"""The named colours the studio gives viser's notifications and progress bar."""


def consistency_rgb(e_v: float, theta_stat: float) -> tuple[int, int, int]:
    """Green at E[v] = 1, yellow half way, red at the removal threshold and below."""
    x = float(np.clip((e_v - theta_stat) / (1.0 - theta_stat), 0.0, 1.0))
    return (int(round(230 * (1 - x) + 40 * x)), int(round(60 * (1 - x) + 190 * x)), 60)


def distance_rgb(d: np.ndarray, cutoff: float) -> np.ndarray:
    """N×3 uint8 colours for distances: dark red inside (< 0), red → yellow → blue up to `cutoff`."""
    x = np.clip(np.asarray(d, float) / max(cutoff, 1e-9), 0.0, 1.0)
    r = np.where(x < 0.5, 1.0, 2.0 * (1.0 - x))
    g = np.where(x < 0.5, 2.0 * x, 1.0 - 0.5 * (x - 0.5))
    b = np.clip(2.0 * x - 0.6, 0.0, 1.0)
    rgb = np.stack([r, g, b], axis=-1)
    rgb[np.asarray(d) < 0.0] = (0.45, 0.0, 0.0)
    return (255 * rgb).astype(np.uint8)
