"""bench/bridge_reaction.py on a few live events through a real bridge (uvicorn on 127.0.0.1) and the reaction
driver in its own process (real MuJoCo): every reaction counted is one to the box the driver placed (the first
command slowed by the drop came from a plan solved after the placement on an EDF holding the box), its parts are
stages that happened in that order on the wall clock the two processes share, and they add up to the whole.
No timing thresholds: the benchmark measures speed."""

from __future__ import annotations

import numpy as np
import pytest

from bench.bridge_reaction import bridge_reaction_figures, measure_bridge_reactions
from bench.bridge_reaction_chain import BRIDGE_PARTS, BridgeReaction
from core.params import HTMPCParams, MappingParams
from tests.bench.reaction_checks import first_slowed, step_that_held_the_box

pytestmark = pytest.mark.wallclock

EVENTS = 3


@pytest.fixture(scope="module")
def run():
    return measure_bridge_reactions(EVENTS, max_wall_s=150.0, keep_s=300.0)


def test_every_reaction_counted_is_one_to_the_box_the_driver_placed(run) -> None:
    assert len(run.events) == EVENTS
    gamma, voxel = HTMPCParams().gamma, MappingParams().edf_voxel_m
    for placement, reaction in run.events:
        assert placement.h_m < placement.v_before_mps / gamma  # the constraint had to act
        command = first_slowed(run.stamps, placement)
        assert reaction.issued_ms == pytest.approx((command.wall - placement.wall) * 1e3)
        step_that_held_the_box(run.stamps, placement, command, voxel)  # in the driver's world


def test_the_parts_happened_in_order_and_add_up_to_the_whole(run) -> None:
    for _, r in run.events:
        assert isinstance(r, BridgeReaction)
        assert list(r.parts_ms) == list(BRIDGE_PARTS)
        assert all(v >= 0.0 for v in r.parts_ms.values()), r.parts_ms
        assert sum(r.parts_ms.values()) == pytest.approx(r.total_ms, abs=1e-6)
        assert r.issued_ms == pytest.approx(r.total_ms - r.parts_ms["delivery"], abs=1e-6)
        assert r.issued_ms == pytest.approx(r.chain.total_ms)
        assert r.parts_ms["link"] + r.parts_ms["mapping"] == pytest.approx(r.chain.parts_ms["mapping"], abs=1e-6)
        assert 0.0 <= r.processing_ms <= r.total_ms
        assert r.chain.sim_ms > 0.0


def test_the_driver_stamps_reach_the_benchmark_in_order(run) -> None:
    """The driver's cycles and applied commands, and the frames' arrivals, come in on one clock, in order."""
    physics = np.array(list(run.stamps.physics))
    assert len(physics) > 100 and np.all(np.diff(physics[:, 0]) > 0) and np.all(np.diff(physics[:, 1]) >= 0)
    applied = np.array(list(run.link.applied))
    assert len(applied) > 100 and np.all(np.diff(applied[:, 1]) >= 0)
    assert len(run.link.arrivals) > 10


def test_the_figures_are_read_from_the_run(run) -> None:
    figures = bridge_reaction_figures(run)
    assert figures["bridge_reaction_events"] == EVENTS
    assert figures["bridge_reaction_ms_p50"] <= figures["bridge_reaction_ms_p95"] <= figures["bridge_reaction_ms_max"]
    assert figures["bridge_processing_ms_p95"] <= figures["bridge_reaction_ms_max"]
    assert all(f"bridge_reaction_{part}_ms_p95" in figures for part in BRIDGE_PARTS)
    assert figures["bridge_hand_frames_integrated_hz"] > 0.0 and figures["bridge_base_frames_integrated_hz"] > 0.0
