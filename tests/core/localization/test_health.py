"""The pose estimate's health on exact synthetic frames: the verdicts counted by outcome, the age of the last
accepted correction, the two reasons a pose is untrusted, and the margin the controller adds."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from core.localization import Localizer
from core.localization.health import margin_growth, position_sigma
from core.params import LocalizationParams
from tests.core.localization.synthetic import FLOOR, surface
from tests.core.localization.test_localizer import BEHIND, CORNER, _drifted_frame, _localizer

DELTA = 0.25


def test_an_accepted_correction_resets_the_age_and_counts_by_outcome():
    loc = _localizer(min_trusted_points=0)
    floor_only, base = _drifted_frame([FLOOR], np.array([0.04, -0.03, 0.0]), t=0.5)
    loc.correct(floor_only, base, surface(BEHIND))  # trusted walls, none in view: degenerate
    frame, base = _drifted_frame(CORNER, np.array([0.04, -0.03, math.radians(1.0)]), t=1.0)
    loc.correct(frame, base, surface(CORNER))
    h = loc.health(1.5, DELTA)
    assert (h.accepted, h.degenerate, h.rejected, h.no_reference) == (1, 1, 0, 0)
    assert h.last_accepted_t == 1.0 and h.since_accepted_s == pytest.approx(0.5)
    assert h.accepted_per_s == pytest.approx(0.5)  # one in the last 2 s
    assert h.sigma_xy_m == pytest.approx(position_sigma(loc.filter.P)) and h.sigma_xy_m < 0.02
    assert h.untrusted is None and h.margin_growth_m == 0.0


def test_no_correction_for_untrusted_after_s_is_untrusted_from_the_start():
    loc = Localizer(LocalizationParams(enabled=True, untrusted_after_s=10.0), start_t=2.0)
    assert loc.health(11.9, DELTA).untrusted is None
    reason = loc.health(12.1, DELTA).untrusted
    assert reason is not None and reason.startswith("no correction accepted for 10.1 s (> 10 s; since the start")


def test_three_sigma_past_half_of_delta_safe_is_untrusted_and_grows_the_margin_capped():
    p = LocalizationParams(enabled=True)
    loc = Localizer(p)
    loc.filter.P = np.diag([0.05**2, 0.03**2, 0.01**2])  # 3σ = 0.15 m > 0.125 m
    h = loc.health(0.1, DELTA)
    assert h.untrusted is not None and "position 3σ 0.15 m exceeds 0.5 × delta_safe (0.12 m)" in h.untrusted
    assert h.margin_growth_m == pytest.approx(0.15 - 0.125)
    assert margin_growth(0.04, DELTA, p) == 0.0  # 3σ = 0.12 m: within half of delta_safe
    assert margin_growth(1.0, DELTA, p) == p.margin_growth_max_m
    assert margin_growth(1.0, DELTA, replace(p, grow_margin=False)) == 0.0


def test_standing_still_with_nothing_to_register_stops_the_untrusted_clock_and_moving_or_a_refusal_runs_it():
    """At a view with nothing to register (here a floor-only frame: degenerate) the base stands 5 s: not untrusted
    after `untrusted_after_s` = 2 s (wheel odometry does not drift at rest, and the view doubts nothing); the
    same frames while it drives 3 s at 0.5 m/s run the clock, and so do refusals at rest."""
    loc = _localizer(min_trusted_points=0, untrusted_after_s=2.0)
    loc.filter.P = np.diag([0.01**2, 0.01**2, 0.001**2])  # well localized a moment ago
    still = np.zeros(3)
    t = 0.0
    while t < 5.0 - 1e-9:
        t = round(t + 0.1, 6)
        loc.predict(still, t)
        if abs(t * 2 - round(t * 2)) < 1e-9:  # a frame every 0.5 s
            floor_only, base = _drifted_frame([FLOOR], np.zeros(3), t=t)
            assert loc.correct(floor_only, base, surface(BEHIND)).verdict.value == "degenerate"
    h = loc.health(t, DELTA)
    assert h.untrusted is None, h.untrusted
    assert h.since_accepted_s == pytest.approx(5.0) and h.at_rest_s == pytest.approx(4.5)  # from the first verdict

    moving = loc.filter.P.copy()
    for k in range(1, 31):  # 3 s at 0.5 m/s, the same view
        t = round(t + 0.1, 6)
        loc.predict(np.array([0.05 * k, 0.0, 0.0]), t)
        if k % 5 == 0:
            floor_only, base = _drifted_frame([FLOOR], np.zeros(3), t=t)
            loc.correct(floor_only, base, surface(BEHIND))
    h = loc.health(t, DELTA)
    assert h.at_rest_s == pytest.approx(4.5) and not np.allclose(loc.filter.P, moving)
    assert h.untrusted is not None and h.untrusted.startswith("no correction accepted for 3.5 s"), h.untrusted
    assert "4.5 s at rest not counted" in h.untrusted

    refused = _localizer(min_trusted_points=0, untrusted_after_s=2.0, max_iterations=0)  # never converges
    refused.filter.P = np.diag([0.01**2, 0.01**2, 0.001**2])
    t = 0.0
    while t < 3.0 - 1e-9:
        t = round(t + 0.1, 6)
        refused.predict(still, t)
        frame, base = _drifted_frame(CORNER, np.zeros(3), t=t)
        assert refused.correct(frame, base, surface(CORNER)).verdict.value == "not_converged"
    h = refused.health(t, DELTA)
    assert h.at_rest_s == 0.0 and h.rejected == 30
    assert h.untrusted is not None and h.untrusted.startswith("no correction accepted for 3.0 s"), h.untrusted
