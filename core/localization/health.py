"""Health of the pose estimate: what the operator sees and what the controller answers with (docs/method.md,
"State estimation"; issue 28, item 2).

The pose is untrusted when
  - no correction has been accepted for longer than `untrusted_after_s` (counted from the start while none has
    been): registrations are rejected, degenerate, or have nothing to register, and odometry drifts on. Time the
    base stood at rest while the latest registration was not a refusal is not counted (`Localizer.rest_s`): at
    rest wheel odometry does not drift, and a view with nothing to register doubts nothing;
  - or trust_sigmas σ_xy > trust_delta_share · delta_safe, with σ_xy = √λ_max(P[:2, :2]) the largest position std:
    the position may be off by more than the collision margin can spare.
The controller's answer (`margin_growth`, our addition): delta_safe grows by what the uncertainty eats of it,
    delta_safe' = delta_safe + clip(trust_sigmas σ_xy − trust_delta_share delta_safe, 0, margin_growth_max_m),
so the true clearance stays at least trust_delta_share · delta_safe while the true pose lies within trust_sigmas σ
(up to the cap). Zero while σ is small: a run whose pose is trusted drives as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.params import LocalizationParams


@dataclass(frozen=True)
class LocalizationHealth:
    """The estimate's health at robot time `t` (s): its covariance and stds, the registrations' verdicts so far,
    the age of the last accepted correction, why the pose is untrusted (None: trusted) and the margin the
    controller adds for it."""

    t: float
    covariance: np.ndarray
    """P (3×3; x, y in m, yaw in rad) of the base's world pose."""
    sigma_xy_m: float
    """√λ_max(P[:2, :2]): the largest position std (m)."""
    sigma_yaw_rad: float
    accepted: int
    """Registrations accepted (corrections), since the start."""
    rejected: int
    """Registrations a gate refused: not converged, few inliers, χ², inconsistent."""
    degenerate: int
    """Registrations that constrained no direction of (x, y, yaw) (e.g. a floor-only view)."""
    no_reference: int
    """Frames with nothing to register: too little trusted surface in view, or too few points in the frame."""
    last_accepted_t: float | None
    """Robot time (s) of the frame of the last accepted correction; None before the first."""
    since_accepted_s: float
    """Robot time (s) since the last accepted correction (since the start before the first)."""
    accepted_per_s: float
    """Corrections accepted per second of robot time over the last `RATE_WINDOW_S`."""
    untrusted: str | None
    """Why the pose is untrusted now, for the operator; None while it is trusted."""
    margin_growth_m: float
    """What the controller adds to delta_safe now (m; 0 with `grow_margin` off)."""
    at_rest_s: float = 0.0
    """Of `since_accepted_s`, the time the base stood at rest with nothing refusing its pose (not counted toward
    `untrusted_after_s`)."""


RATE_WINDOW_S = 2.0
"""The correction rate is counted over this much robot time (s)."""


def position_sigma(P: np.ndarray) -> float:
    """σ_xy = √λ_max(P[:2, :2]) (m)."""
    return float(math.sqrt(max(float(np.max(np.linalg.eigvalsh(np.asarray(P, float)[:2, :2]))), 0.0)))


def margin_growth(sigma_xy_m: float, delta_safe_m: float, p: LocalizationParams) -> float:
    """clip(trust_sigmas σ_xy − trust_delta_share delta_safe, 0, margin_growth_max_m), 0 with `grow_margin` off."""
    if not p.grow_margin:
        return 0.0
    return float(np.clip(p.trust_sigmas * sigma_xy_m - p.trust_delta_share * delta_safe_m, 0.0,
                         p.margin_growth_max_m))


def untrusted_reason(sigma_xy_m: float, since_accepted_s: float, accepted: int, rejected: int, degenerate: int,
                     no_reference: int, delta_safe_m: float, p: LocalizationParams, at_rest_s: float = 0.0
                     ) -> str | None:
    """Why the pose is untrusted (both reasons when both hold), or None. `at_rest_s` of `since_accepted_s` do not
    count toward `untrusted_after_s`."""
    reasons = []
    counted = since_accepted_s - at_rest_s
    if counted > p.untrusted_after_s:
        what = (f"{rejected} rejected, {degenerate} degenerate, {no_reference} with nothing to register"
                if rejected + degenerate + no_reference else "no registration")
        ever = "since the start" if accepted == 0 else "since the last"
        rest = f", {at_rest_s:.1f} s at rest not counted" if at_rest_s > 0 else ""
        reasons.append(f"no correction accepted for {counted:.1f} s (> {p.untrusted_after_s:g} s; "
                       f"{ever}: {what}{rest})")
    limit = p.trust_delta_share * delta_safe_m
    if p.trust_sigmas * sigma_xy_m > limit:
        reasons.append(f"position {p.trust_sigmas:g}σ {p.trust_sigmas * sigma_xy_m:.2f} m exceeds "
                       f"{p.trust_delta_share:g} × delta_safe ({limit:.2f} m)")
    return "; ".join(reasons) if reasons else None
