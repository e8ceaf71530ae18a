"""One name per mapped object (issue 31, item 1): an object the operator named (Names tab, or a sequence's
`objects`) reads '#4 box_3' alike in its 3D label, the E[v] legend and the recordings (studio JSON and Foxglove
scene); the Names tab lists and binds it as '#4', and draws no second label of its own that could print over
a neighbour's."""

import numpy as np
import pytest
import viser

from app.object_label import map_id, operator_names, shown_id
from app.recording.foxglove_scene import mapped_objects as foxglove_objects
from app.recording.topics import snapshot_messages
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState, Snapshot
from app.target_check import named_boxes
from app.ui.anchor_panel import AnchorPanel, binding_lines
from app.ui.map_view import MapView
from app.ui.monitor_panel import MonitorPanel
from core.params import MappingParams
from core.scene import load_scene
from core.types import MappedObject, ObjectMapSnapshot, RobotState
from tasks import load_sequence
from tasks.anchors import MapObjects, ObjectView
from tasks.sequence_file import EXAMPLES_DIR
from tasks.sequencer import SubtaskProgress
from tests.app.conftest import free_port


def named_snapshot(t: float = 2.0) -> Snapshot:
    """Objects #4 and #5 side by side on one table; #4 named box_3 and a subtask anchored on it."""
    objects = []
    for i, xyz in ((4, (2.0, 1.0, 0.9)), (5, (2.35, 1.1, 0.9))):
        pose = np.eye(4)
        pose[:3, 3] = xyz
        objects.append(MappedObject(i, pose, np.array([0.3, 0.3, 0.3]), np.zeros((0, 3)), MappingParams().prior(),
                                    last_seen_t=1.0))
    view = ObjectView("object_4", "box_3", np.array([2.0, 1.0, 0.9]), 0.0, np.array([0.3, 0.3, 0.3]))
    free = ObjectView("object_5", None, np.array([2.35, 1.1, 0.9]), 0.0, np.array([0.3, 0.3, 0.3]))
    progress = (SubtaskProgress(0, "pick", "ee", anchor_object="box_3", anchor_label="top of box_3"),)
    return Snapshot(seq=0, wall_time=0.0, state=RobotState(t, np.zeros(9), np.zeros(9)), run_state=RunState.RUNNING,
                    object_map=ObjectMapSnapshot(t, tuple(objects)), anchors=MapObjects(t, (view, free)),
                    progress=progress)


def test_ids_read_as_the_map_names_them():
    assert map_id("object_12") == 12 and map_id("box_a") is None and map_id("object_x") is None
    assert shown_id("object_12") == "#12" and shown_id("box_a") == "box_a"
    assert operator_names(named_snapshot().anchors) == {4: "box_3"} and operator_names(None) == {}
    # the boxes target checks and problems speak of (an anchored target rechecked after its object moved)
    assert named_boxes(named_snapshot().anchors)["box_3"].id == "#4"


def test_a_named_object_has_one_name_in_the_view_the_legend_the_names_tab_and_the_recordings(robot):
    snap = named_snapshot()
    server = viser.ViserServer(port=free_port())
    try:
        view = MapView(server, robot)
        view.update(snap)
        drawn = view.drawn_objects()
        assert drawn[4].label.startswith("#4 box_3 E[v]=") and drawn[5].label.startswith("#5 E[v]=")

        monitor = MonitorPanel(server)
        monitor.build_plots()
        monitor.update(snap)
        assert monitor.object_labels()[:2] == ["#4 box_3", "#5"]

        names = AnchorPanel(server, runtime=None)
        names.update(snap)
        assert tuple(names.object.options)[1:] == ("#4", "#5")
        names.select("object_5")  # a click on #5's shell
        assert names.object.value == "#5" and names.selected_id() == "object_5"
        assert binding_lines(snap) == ["1. pick: top of box_3 → #4"]
        assert not any("/anchors/names/" in h.name for h in names._drawn)  # the name is in #4's own label
    finally:
        server.stop()

    posterior = dict(snapshot_messages(snap))["/map/posterior"]
    assert [o["label"] for o in posterior["objects"]] == ["#4 box_3", "#5"]
    assert snap.object_map is not None
    scene = foxglove_objects(snap.state.t, snap.object_map, 0.4, operator_names(snap.anchors))
    assert b"#4 box_3 E[v]=" in scene and b"#5 E[v]=" in scene


@pytest.mark.slow
def test_a_name_given_while_paused_shows_at_once_on_a_sequence_that_names_nothing():
    """two_pickups declares no objects: a name given in the Names tab (here while paused) reaches the snapshot the
    labels and the legend are drawn from at once, not at the next control step or the next run."""
    path = EXAMPLES_DIR / "two_pickups.yaml"
    sequence = load_sequence(path)
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=load_scene((path.parent / sequence.scene).resolve()),
                 sequence=sequence)
    rt.start()
    rt.run_lockstep(3.0, until_done=False)
    rt.pause()
    snap = rt.snapshot()
    assert snap.object_map is not None and snap.object_map.objects and operator_names(snap.anchors) == {}
    first = snap.object_map.objects[0].id
    rt.name_object("crate", f"object_{first}")
    assert operator_names(rt.snapshot().anchors) == {first: "crate"}
