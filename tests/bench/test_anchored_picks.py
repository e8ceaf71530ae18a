"""The anchored-picks benchmark's parts: the world-frame twin of the example puts each pick where lap 1 has
its box, laps repeat the example with the lap starts where the boxes move, and the moves leave every lap's
targets admissible."""

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.target_check import envelope_of, scene_obstacles
from bench.anchored_picks import EXAMPLE, _Trial, laps_of, world_frame
from core.scene import load_scene
from tasks.schema import EESubtask
from tasks.sequence_file import load_sequence
from tasks.validation import Severity, check_sequence


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


def test_moves_keep_each_lap_admissible():
    """Seed 0's first draw for lap 3 put box_a's approach stance 0.52 m from box_b (the base keeps 0.80 m): it is
    drawn again, and after every lap's moves its targets pass the target checks on the true boxes."""
    laps, starts = laps_of(load_sequence(EXAMPLE), 3)
    anchors = {i: a for i, s in enumerate(laps.subtasks) if isinstance(s, EESubtask) and (a := s.goal().anchor)}
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=load_scene((EXAMPLE.parent / laps.scene).resolve()),
                 sequence=laps)
    trial = _Trial(laps, anchors, starts, np.random.default_rng(0))
    try:
        for start, end in zip(starts, (*starts[1:], len(laps.subtasks)), strict=True):
            before = {n: rt.require_world().box(n).position for n in ("box_a", "box_c")}
            for name, position in trial._moves(rt, start).items():
                rt.move_box(name, position)
            boxes = {o.id: o for o in scene_obstacles(rt)}
            for name, was in before.items():
                assert 0.3 <= np.linalg.norm(np.subtract(boxes[name].position, was)) <= 0.5
            findings = check_sequence(laps, tuple(boxes.values()), envelope_of(rt), indices=range(start, end),
                                      anchors={n: boxes[n] for n in ("box_a", "box_c")})
            assert not [f for f in findings if f.severity == Severity.ERROR]
        assert trial.moves_redrawn == 1
    finally:
        rt.shutdown()
