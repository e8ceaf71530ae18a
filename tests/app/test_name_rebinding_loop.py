"""A name found again after its box moved out of view, in the closed loop (lockstep, MuJoCo, the object map
through the whole sensor model): two laps of the bench's example (`bench/anchored_picks.py`), whose boxes move
0.3-0.5 m at lap 2's start while the robot is at the start; judged against the simulator's true boxes.

- seed 3, localization off: box_c moves 0.42 m diagonally; its new place is mapped as a new object while the
  old one is still matched (the two overlap), so the name must re-bind by where the box stood (footprints at
  the box's size; a circle test missed it).
- seed 4, localization on: box_a was mapped 1.19 m long (its old and new places fused) when POCD removed it; its
  new object must be compared with the box's declared size, not that extent. That fusion came from the localizer
  following the moved box (22 cm off for lap 2); since it no longer does (docs/decisions.md, "A moved box pulled a
  right pose") the pose stays within 3 cm, and the case fails on the map instead: box_a's old place keeps a band at
  the base camera's height that nothing is seen through (the floor behind it beyond the range), and the object
  stays 0.97 m long. The approach now completes on it after 5 s (`anchor_base_settle_s`), the pick waits until the
  hand camera settles the box and completes, but 5.3 cm from the true box (limit 5 cm). Strict, so a fix shows."""

import pytest

from bench.anchored_picks import EXAMPLE, ON_BOX_M, laps_of, run
from tasks.schema import EESubtask
from tasks.sequence_file import load_sequence


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "localization"), [
    (3, False),
    pytest.param(4, True, marks=pytest.mark.xfail(strict=True, reason="lap 2's pick above box_a completes 5.3 cm "
                                                  "from the true box (limit 5): the map settled the box that far off")),
])
def test_a_box_moved_out_of_view_is_named_again_and_picked_on_the_true_box(seed, localization):
    sequence, lap_starts = laps_of(load_sequence(EXAMPLE), 2)
    anchors = {i: a for i, s in enumerate(sequence.subtasks)
               if isinstance(s, EESubtask) and (a := s.goal().anchor) is not None}
    trial = run(sequence, sequence, anchors, lap_starts, seed=seed, max_s=sum(s.timeout_s for s in sequence.subtasks),
                localization=localization)
    lap2 = [p for p in trial.picks if p["subtask"].startswith("lap 2")]
    assert [p["subtask"] for p in lap2] == ["lap 2: pick above box_a", "lap 2: pick above box_c"], trial.picks
    assert all(p["outcome"] == "done" and p["error_m"] <= ON_BOX_M for p in lap2), lap2
    assert trial.subtasks_done == len(sequence.subtasks)
