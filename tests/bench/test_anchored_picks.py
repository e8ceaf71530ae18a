"""The anchored-picks benchmark's parts: the world-frame twin of the example puts each pick where lap 1 has
its box, and laps repeat the example with the lap starts where the boxes move."""

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from bench.anchored_picks import EXAMPLE, laps_of, world_frame
from core.scene import load_scene
from tasks.schema import EESubtask
from tasks.sequence_file import load_sequence


def test_world_frame_twin_and_laps():
    seq = load_sequence(EXAMPLE)
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=load_scene((EXAMPLE.parent / seq.scene).resolve()),
                 sequence=seq)
    twin = world_frame(seq, rt)
    approach, pick = twin.subtasks[0], twin.subtasks[1]
    assert isinstance(pick, EESubtask) and pick.target is not None and pick.target.anchor is None
    box_a = rt.require_world().box("box_a")
    np.testing.assert_allclose(pick.target.position, (box_a.position[0], box_a.position[1] - 0.25, 0.6 + 0.7))
    assert approach.goal().anchor is None and (approach.goal().x, approach.goal().y) == pytest.approx((2.2, 0.15))
    assert twin.subtasks[4] == seq.subtasks[4]  # world targets stay as they are
    laps, starts = laps_of(seq, 3)
    assert len(laps.subtasks) == 15 and starts == (5, 10) and laps.subtasks[5].name == "lap 2: approach box_a"
