"""The studio's names tab on a real runtime and viser server: name a mapped object, author 'Reach its top' /
'Approach its front' on it, and see the binding (goal frame on the object, a line to it, the list)."""

from collections.abc import Iterator

import numpy as np
import pytest
import viser

from app.runtime import Runtime, RuntimeConfig
from app.ui.anchor_panel import APPROACH_FRONT, REACH_TOP, AnchorPanel, binding_lines
from core.scene import Box, Scene
from tasks.schema import TaskSequence
from tests.app.conftest import free_port


@pytest.fixture
def tab() -> Iterator[tuple[Runtime, AnchorPanel]]:
    """The Names tab on a real viser server, over a runtime on the ground-truth map (boxes 'crate' and 'far')."""
    scene = Scene((Box("crate", (2.5, 0.0, 0.3)), Box("far", (0.0, 4.0, 0.3))), robot_start=(0.0, 0.0, 0.0))
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=scene, sequence=TaskSequence())
    server = viser.ViserServer(port=free_port())
    try:
        panel = AnchorPanel(server, rt)
        panel.update(rt.snapshot())
        yield rt, panel
    finally:
        server.stop()
        rt.shutdown()


def test_name_an_object_author_on_it_and_see_the_binding(tab):
    rt, panel = tab
    assert "crate" in panel.object.options and "/anchors/pick/crate" in str(panel._picks["crate"][1].name)
    panel.select("crate")  # what a click on its shell does
    panel.name.value = "box_3"
    panel.add_anchored("approach", APPROACH_FRONT)
    panel.add_anchored("reach", REACH_TOP)
    seq = rt.sequence
    assert list(seq.objects) == ["box_3"] and seq.objects["box_3"].position == (2.5, 0.0, 0.3)
    assert [s.name for s in seq.subtasks] == ["approach front of box_3", "reach top of box_3"]
    rt.run_lockstep(1.0, until_done=False)
    snap = rt.snapshot()
    panel.update(snap)
    assert binding_lines(snap)[0] == "1. approach front of box_3: front of box_3 + (-0.9, 0, 0) → crate"
    assert snap.progress[0].anchored_goal is not None and abs(snap.progress[0].anchored_goal[0] - 1.3) < 1e-6
    assert panel._drawn_key is not None and len(panel._drawn) == 3  # name label, goal frame, line


def test_a_name_takes_the_declared_size_and_a_bad_size_is_refused(tab):
    """*Size (m)* in the Names tab: a size typed with the name is declared (saved with the sequence, and the name's
    known size at once); all 0 is unknown; a side that is 0, negative or NaN refuses the naming with the reason."""
    rt, panel = tab
    panel.select("far")
    panel.name.value = "bin"
    assert panel.declared_size() is None  # all 0: unknown
    for bad in ((0.6, 0.0, 0.6), (0.6, -0.5, 0.6), (0.6, float("nan"), 0.6)):
        panel.size.value = bad
        with pytest.raises(ValueError, match="every side a number > 0"):
            panel.declared_size()
        panel._guarded(panel.name_selected)  # what the button does: a notice, nothing named
        assert rt.closed_loop.names.bound() == {} and rt.sequence.objects == {}
    panel.size.value = (0.6, 0.5, 0.6)
    panel.select("crate")
    panel.name.value = "box_3"
    panel._guarded(panel.name_selected)
    assert rt.sequence.objects["box_3"].size == (0.6, 0.5, 0.6)
    view = rt.snapshot().anchors
    assert view is not None
    named = view.named("box_3")
    assert named is not None and named.id == "crate" and named.size is not None
    np.testing.assert_allclose(named.size, (0.6, 0.5, 0.6))


def test_anchored_progress_survives_a_recording():
    import json

    from app.recording.topics import snapshot_from_messages, snapshot_messages
    from tasks.sequence_file import parse_sequence

    seq = parse_sequence("objects: {box_3: {}}\nsubtasks:\n- kind: ee\n  target: {anchor: {object: box_3}}\n")
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene((Box("box_3", (2.5, 0.0, 0.3)),)), sequence=seq)
    messages = dict(snapshot_messages(rt.snapshot()))
    back = snapshot_from_messages(json.loads(json.dumps(messages)))
    assert back.progress[0].anchor_object == "box_3" and back.progress[0].anchor_label == "top of box_3"
