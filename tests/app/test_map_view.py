"""The map view draws live objects coloured by E[v]; removed ones stay visible (grey, labelled) at their last
known pose until the map starts over."""

import numpy as np
import viser

from app.runtime.snapshot import Snapshot
from app.ui.map_view import MapView
from core.params import MappingParams
from core.types import MappedObject, ObjectMapSnapshot, RobotState
from tests.app.conftest import free_port


def snap(objects, removed=(), t=0.0):
    state = RobotState(t, np.zeros(9), np.zeros(9))
    return Snapshot(seq=0, wall_time=0.0, state=state, object_map=ObjectMapSnapshot(0.0, tuple(objects), removed))


def test_removed_object_drawn_at_last_pose(robot):
    server = viser.ViserServer(port=free_port())
    try:
        view = MapView(server, robot)
        pose = np.eye(4)
        pose[:3, 3] = [2.0, 1.0, 0.3]
        prior = MappingParams().prior()
        obj = MappedObject(3, pose, np.array([0.6, 0.6, 0.6]), np.zeros((0, 3)), prior, last_seen_t=0.0)
        view.update(snap([obj]))
        assert view.drawn_objects()[3].label == f"#3 E[v]={prior.consistency:.2f} · seen now"

        view.update(snap([], removed=(3,), t=12.4))
        drawn = view.drawn_objects()
        assert list(drawn) == [3]
        assert drawn[3].label == "#3 removed · seen 12 s ago"
        np.testing.assert_allclose(drawn[3].position, [2.0, 1.0, 0.3])

        view.update(snap([]))  # a new, empty map: nothing left to draw
        assert view.drawn_objects() == {}
    finally:
        server.stop()


def test_labels_of_neighbouring_objects_never_overprint(robot):
    """Two objects side by side on one table (and a third on top): their labels are stacked apart in height."""
    server = viser.ViserServer(port=free_port())
    try:
        view = MapView(server, robot)
        prior = MappingParams().prior()
        objects = []
        for i, xyz in enumerate([(2.0, 1.0, 0.9), (2.35, 1.1, 0.9), (2.0, 1.0, 1.5), (5.0, 1.0, 0.9)]):
            pose = np.eye(4)
            pose[:3, 3] = xyz
            objects.append(MappedObject(i + 1, pose, np.array([0.3, 0.3, 0.3]), np.zeros((0, 3)), prior,
                                        last_seen_t=1.0))
        view.update(snap(objects, t=5.0))
        drawn = view.drawn_objects()
        labels = {i: np.array(d.label_position) for i, d in drawn.items()}
        near = [(a, b) for a in labels for b in labels if a < b and np.hypot(*(labels[a] - labels[b])[:2]) < 0.8]
        assert near  # the first three are neighbours
        assert all(abs(labels[a][2] - labels[b][2]) >= 0.22 - 1e-9 for a, b in near)
        assert labels[4][2] == 0.9 + 0.15 + 0.15  # alone: right above its top
        assert drawn[2].label.startswith("#2 ") and "seen 4 s ago" in drawn[2].label
    finally:
        server.stop()
