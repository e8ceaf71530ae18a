"""`DistanceField`: all the controller needs of a map (`core.types.LocalEDF` satisfies it), in a module of its
own so that both consumers, the sphere rows (`collision_constraint.py`) and the base's box rows
(`box_barrier.py`), import it without importing each other."""

from __future__ import annotations

from typing import Protocol

import numpy as np

__all__ = ["DistanceField", "distance_and_gradient"]


class DistanceField(Protocol):
    """What the controller needs of a map (`core.types.LocalEDF` satisfies it)."""

    def distance(self, p: np.ndarray) -> np.ndarray: ...

    def gradient(self, p: np.ndarray) -> np.ndarray: ...


def distance_and_gradient(edf: DistanceField, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """EDF value and gradient at p, from one lookup where the field offers it (`LocalEDF`)."""
    both = getattr(edf, "distance_and_gradient", None)
    return both(p) if both is not None else (edf.distance(p), edf.gradient(p))
