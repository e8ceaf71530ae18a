"""bench.localization's correction figures: the issue's false corrections, and the pulls away from the truth apart."""

from __future__ import annotations

import math

import numpy as np

from bench.localization import correction_errors, false_corrections_pct, pulled_away_pct
from core.localization import se2
from core.localization.correction import Correction
from core.localization.gates import Verdict


def _result(corrections: list[Correction]) -> dict:
    """A straight drive along x at 1 m/s, heading 0, the truth sampled every 0.1 s; no camera latency."""
    rows = [(t, 0, np.array([t, 0.0, 0.0]), np.array([t, 0.0, 0.0]), np.array([t, 0.0, 0.0]))
            for t in np.arange(0.0, 10.0, 0.1)]
    return {"rows": rows, "corrections": corrections, "latency_s": 0.0}


def _accepted(t: float, before: np.ndarray, after: np.ndarray) -> Correction:
    """An accepted correction taking the pose `before` to `after` at time t (Δ with after = Δ ∘ before)."""
    delta = se2.compose(after, se2.inverse(before))
    return Correction(t=t, verdict=Verdict.ACCEPTED, delta=delta, pose=after)


def test_errors_before_and_after_each_accepted_correction() -> None:
    c = _accepted(2.0, np.array([2.03, 0.04, 0.0]), np.array([2.0, 0.01, math.radians(0.5)]))
    e = correction_errors(_result([c, Correction(t=3.0, verdict=Verdict.CHI2)]))
    assert e.shape == (1, 4)
    np.testing.assert_allclose(e[0], [0.05, 0.01, 0.0, 0.5], atol=1e-9)


def test_a_correction_towards_the_truth_is_no_pull_even_while_the_pose_stays_off() -> None:
    healing = _accepted(1.0, np.array([1.0, 0.12, 0.0]), np.array([1.0, 0.08, 0.0]))
    e = correction_errors(_result([healing]))
    assert false_corrections_pct(e) == 100.0  # still 8 cm off: the figure counts it
    assert pulled_away_pct(e) == 0.0


def test_a_correction_that_drags_the_pose_away_is_a_pull() -> None:
    dragged = _accepted(4.0, np.array([4.0, 0.01, 0.0]), np.array([4.0, 0.04, 0.0]))
    turned = _accepted(5.0, np.array([5.0, 0.0, 0.0]), np.array([5.0, 0.0, math.radians(0.4)]))
    fine = _accepted(6.0, np.array([6.0, 0.005, 0.0]), np.array([6.0, 0.002, 0.0]))
    e = correction_errors(_result([dragged, turned, fine]))
    assert math.isclose(pulled_away_pct(e), 100.0 * 2 / 3)
    assert false_corrections_pct(e) == 0.0  # all within 5 cm and 1° after


def test_no_accepted_correction_gives_no_figure() -> None:
    e = correction_errors(_result([Correction(t=1.0, verdict=Verdict.DEGENERATE)]))
    assert math.isnan(pulled_away_pct(e)) and math.isnan(false_corrections_pct(e))
