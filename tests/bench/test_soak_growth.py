"""bench/soak.py's memory growth: fitted over whole sawtooth periods of cycles 100–200, so the saw does not
pass for growth (or hide it); fewer cycles say they cannot tell."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.soak import ApiTally, growth_over_periods, sawtooth_period


def _saw(n: int, slope: float, period: int = 12, height: float = 6.0) -> np.ndarray:
    cycles = np.arange(n)
    return 800.0 + slope * cycles + height * (cycles % period) / period


@pytest.mark.parametrize("slope", [0.0, 0.3])
def test_growth_over_whole_periods_finds_the_slope_under_the_saw(slope: float) -> None:
    values = _saw(101, slope)
    assert sawtooth_period(values) == 12
    growth, period, used = growth_over_periods(values)
    assert period == 12 and (used - 1) % 12 == 0
    assert growth == pytest.approx(slope, abs=0.05)


def _tally(cycles: int, slope: float) -> ApiTally:
    tally = ApiTally(cycles=cycles)
    warmup = np.minimum(np.arange(cycles + 1), 100) * 1.3  # the floor rises over the first 100 cycles
    for i, rss in enumerate(_saw(cycles + 1, slope) + warmup):
        tally.rss.append((float(i), float(rss)))
    tally.threads = tally.children = [1] * (cycles + 1)
    tally.contexts = [0, 2, 2]
    return tally


def test_200_cycles_tell_flat_from_growing_and_a_quick_run_says_it_cannot() -> None:
    assert _tally(200, 0.0).figures()["api_rss_growth_mb_per_cycle"] == pytest.approx(0.0, abs=0.05)
    assert _tally(200, 0.5).figures()["api_rss_growth_mb_per_cycle"] == pytest.approx(0.5, abs=0.05)
    quick = _tally(20, 0.0)
    assert math.isnan(quick.figures()["api_rss_growth_mb_per_cycle"])
    assert "cannot be told from 20 cycles" in quick.growth_note()
