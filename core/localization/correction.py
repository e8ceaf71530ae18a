"""`Correction`: what one registration of a frame did to the pose estimate (against the map's surfaces, or a loop
closure onto an earlier visit's keyframes), as the localizer records it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from core.localization.gates import Verdict


@dataclass(frozen=True)
class Correction:
    """What one registration did: its verdict, the world-frame correction Δ (x, y, yaw; zero unless
    accepted), the directions it constrained, its NIS, inlier share, times and the objects that disagreed."""

    t: float
    verdict: Verdict
    delta: np.ndarray = field(default_factory=lambda: np.zeros(3))
    dof: int = 0
    nis: float = math.nan
    inlier_share: float = math.nan
    registration_ms: float = math.nan
    reference_ms: float = 0.0
    disagreeing: tuple[int, ...] = ()
    off: tuple[int, ...] = ()
    """Inconsistent only: the objects found off their surfaces (most of those judged); unlike `disagreeing`, neither
    left out of the reference nor handed to the map (the pose was in doubt, not they)."""
    apply_t: float = math.nan
    pose: np.ndarray | None = None
    """The base's world pose at the frame's exposure after the correction (accepted ones only)."""
    loop: bool = False
    """Whether the frame was registered against an earlier visit's keyframes (a loop closure), not the map."""
    jump: bool = True
    """A χ² refusal: whether its innovation (along the constrained directions) is as large as a jump
    (`lost_jump_m`, `lost_jump_rad`); a smaller one says the filter was too sure, not that the base slipped."""
    innovation: np.ndarray | None = None
    """A χ² refusal: measured ⊖ predicted (x, y, yaw) along the constrained directions."""
