"""The anchored-picks benchmark's parts: the world-frame twin of the example puts each pick where lap 1 has
its box, and laps repeat the example with the lap starts where the boxes move."""

import numpy as np

from app.runtime import Runtime, RuntimeConfig
from bench.anchored_picks import EXAMPLE, laps_of, world_frame
from core.sim.scene import load_scene
from tasks.schema import EESubtask
from tasks.sequence_file import load_sequence


def test_world_frame_twin_and_laps():
    seq = load_sequence(EXAMPLE)
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=load_scene((EXAMPLE.parent / seq.scene).resolve()),
                 sequence=seq)
    twin = world_frame(seq, rt)
    pick = twin.subtasks[0]
    assert isinstance(pick, EESubtask) and pick.target is not None and pick.target.anchor is None
    box_a = rt.require_world().box("box_a")
    np.testing.assert_allclose(pick.target.position, (box_a.position[0] - 0.25, box_a.position[1], 0.6 + 0.7))
    assert twin.subtasks[2] == seq.subtasks[2]  # world targets stay as they are
    laps, starts = laps_of(seq, 3)
    assert len(laps.subtasks) == 9 and starts == (3, 6) and laps.subtasks[3].name == "lap 2: pick above box_a"
