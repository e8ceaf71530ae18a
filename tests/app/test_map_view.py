"""The map view draws live objects coloured by E[v]; removed ones stay visible (grey, labelled) at their last
known pose until the map starts over."""

import numpy as np
import viser

from app.runtime.snapshot import Snapshot
from app.ui.map_view import MapView
from core.params import MappingParams
from core.types import MappedObject, ObjectMapSnapshot, RobotState
from tests.app.conftest import free_port


def snap(objects, removed=()):
    state = RobotState(0.0, np.zeros(9), np.zeros(9))
    return Snapshot(seq=0, wall_time=0.0, state=state, object_map=ObjectMapSnapshot(0.0, tuple(objects), removed))


def test_removed_object_drawn_at_last_pose(robot):
    server = viser.ViserServer(port=free_port())
    try:
        view = MapView(server, robot)
        pose = np.eye(4)
        pose[:3, 3] = [2.0, 1.0, 0.3]
        prior = MappingParams().prior()
        obj = MappedObject(3, pose, np.array([0.6, 0.6, 0.6]), np.zeros((0, 3)), prior)
        view.update(snap([obj]))
        assert view.drawn_objects()[3].label == f"#3 E[v]={prior.consistency:.2f}"

        view.update(snap([], removed=(3,)))
        drawn = view.drawn_objects()
        assert list(drawn) == [3]
        assert drawn[3].label.endswith(" removed")
        np.testing.assert_allclose(drawn[3].position, [2.0, 1.0, 0.3])

        view.update(snap([]))  # a new, empty map: nothing left to draw
        assert view.drawn_objects() == {}
    finally:
        server.stop()
