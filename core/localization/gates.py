"""Gates: a registration corrects the pose only if it converged on enough points, enough of its points found
a partner (inlier share), and its innovation passes a χ² test against the prediction."""

from __future__ import annotations

from enum import StrEnum

from core.params import LocalizationParams


class Verdict(StrEnum):
    """What became of one registration."""

    ACCEPTED = "accepted"
    NO_REFERENCE = "no_reference"
    """Too little trusted surface in view: odometry stays alone in charge (start-up, after Reset)."""
    TOO_FEW_POINTS = "too_few_points"
    NOT_CONVERGED = "not_converged"
    FEW_INLIERS = "few_inliers"
    DEGENERATE = "degenerate"
    """No direction of (x, y, yaw) constrained (e.g. a floor-only view)."""
    CHI2 = "chi2"
    INCONSISTENT = "inconsistent"
    """Most objects in view disagree with the reference: the pose, not the objects, is in doubt."""
    SEARCHED = "searched"
    """Lost: the frame went to the global search (`lost.py`), not to a registration; neither counted nor tallied."""


FAILURES = (Verdict.TOO_FEW_POINTS, Verdict.NOT_CONVERGED, Verdict.FEW_INLIERS)
"""Verdicts that are registration failures (odometry in charge, counted)."""


def registration_verdict(converged: bool, inliers: int, source_points: int, p: LocalizationParams) -> Verdict | None:
    """The failure of a registration, or None if it passes the convergence and inlier-share gates."""
    if source_points < p.min_source_points:
        return Verdict.TOO_FEW_POINTS
    if not converged:
        return Verdict.NOT_CONVERGED
    if inliers < p.min_inlier_share * source_points:
        return Verdict.FEW_INLIERS
    return None


def chi2_passes(nis: float, dof: int, p: LocalizationParams) -> bool:
    """χ² test of the normalised innovation squared with `dof` constrained directions (1 % tail)."""
    return 1 <= dof <= 3 and nis <= p.chi2_gate[dof - 1]
