"""bench/reaction.py on a few live events: every reaction counted is one to the box (checked again here from the
stamps: the first command slowed by the drop came from a plan solved after the placement on an EDF holding the box,
the box constraining when it appeared), and its parts are stages that happened in order and add up to the whole.
No timing thresholds: the benchmark measures speed."""

from __future__ import annotations

import pytest

from bench.reaction import measure_reactions
from bench.reaction_chain import PARTS, Reaction
from core.params import HTMPCParams, MappingParams
from tests.bench.reaction_checks import first_slowed, step_that_held_the_box

pytestmark = pytest.mark.wallclock

EVENTS = 3


@pytest.fixture(scope="module")
def run():
    return measure_reactions(EVENTS, max_wall_s=120.0, keep_s=300.0)


def test_every_reaction_counted_is_one_to_the_box(run) -> None:
    assert len(run.events) == EVENTS
    gamma, voxel = HTMPCParams().gamma, MappingParams().edf_voxel_m
    for placement, reaction in run.events:
        assert placement.h_m < placement.v_before_mps / gamma  # the constraint had to act
        command = first_slowed(run.stamps, placement)
        assert reaction.total_ms == pytest.approx((command.wall - placement.wall) * 1e3)
        step = step_that_held_the_box(run.stamps, placement, command, voxel)
        seen = [f for i in run.stamps.integrations if placement.wall < i.wall_end <= step.wall_edf for f in i.frames
                if f.exposure_t > placement.t]
        assert seen  # a frame taken after the placement reached the map before that step


def test_the_parts_happened_in_order_and_add_up_to_the_whole(run) -> None:
    for _, r in run.events:
        assert isinstance(r, Reaction)
        assert list(r.parts_ms) == list(PARTS)
        assert all(v >= 0.0 for v in r.parts_ms.values()), r.parts_ms
        assert sum(r.parts_ms.values()) == pytest.approx(r.total_ms, abs=1e-6)
        assert 0.0 <= r.processing_ms <= r.total_ms
        assert r.sim_ms > 0.0


def test_the_loops_health_is_read_from_the_same_run(run) -> None:
    health = run.health
    assert health["control_steps"] > 0 and 0.0 <= health["control_late_pct"] <= 100.0
    assert health["hand_frames_integrated_hz"] > 0.0 and health["base_frames_integrated_hz"] > 0.0


def test_each_new_plan_is_commanded_by_the_control_thread_as_it_is_solved(run) -> None:
    """Live, with no modelled actuation delay, a plan's first command does not wait for the next I/O tick: the
    control thread sends it right after the solve (the I/O thread's ticks go on with it after)."""
    controls = [c for c in run.stamps.controls if c.plan is not None]
    commands = list(run.stamps.commands)
    first_by = {}
    for command in commands:
        if command.plan is not None and id(command.plan) not in first_by:
            first_by[id(command.plan)] = command
    commanded = [first_by[id(c.plan)] for c in controls if id(c.plan) in first_by]
    assert len(commanded) >= len(controls) - 1  # the last plan may not have been commanded before the stop
    assert commanded and all(c.thread == "control" for c in commanded), {c.thread for c in commanded}
    assert any(c.thread == "io" for c in commands)
