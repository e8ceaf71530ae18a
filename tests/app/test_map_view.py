"""Removed objects stay visible (grey, labelled) at their last known pose."""

import numpy as np
import viser

from app.snapshot import Snapshot
from app.ui.map_view import MapView
from core.types import MappedObject, ObjectMapSnapshot, Posterior, RobotState
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
        obj = MappedObject(3, pose, np.array([0.6, 0.6, 0.6]), np.zeros((0, 3)), Posterior(alpha=1.0, beta=2.0))
        view.update(snap([obj]))
        assert [(o.id, removed) for o, removed in view._objects_to_draw(snap([obj]))] == [(3, False)]
        drawn = view._objects_to_draw(snap([], removed=(3,)))
        assert [(o.id, removed) for o, removed in drawn] == [(3, True)]
        np.testing.assert_allclose(drawn[0][0].pose[:3, 3], [2.0, 1.0, 0.3])
        view.update(snap([], removed=(3,)))
        assert 3 in view._objects
    finally:
        server.stop()
