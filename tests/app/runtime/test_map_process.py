"""The map in its own process answers as the same map in this process would; its failures are errors."""

from __future__ import annotations

import os
import signal
from dataclasses import replace

import numpy as np
import pytest

import core.sim  # noqa: F401  (GL backend first)
from app.runtime.map_process import MapProcess, MapProcessError
from core.mapping import ObjectMapper
from core.params import MappingParams
from core.robot.model import RobotModel
from core.scene import Box, Scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from tests.app.bridge.conftest import wait_until

pytestmark = pytest.mark.wallclock


@pytest.fixture(scope="module")
def observations():
    robot = RobotModel()
    sim = SimRobot(SimWorld(robot, scene=Scene((Box("a", (2.0, 0.3, 0.3)),))))
    sim.observe()
    out = []
    for _ in range(4):
        sim.step(0.1)
        out.append(sim.observe())
    sim.close()
    return robot, out


def test_the_isolated_map_matches_the_same_map_here(observations):
    robot, obs = observations
    here, there = ObjectMapper(robot, MappingParams()), MapProcess(ObjectMapper(robot, MappingParams()))
    try:
        for o in obs[:2]:  # the map works here until the worker is ready, then moves there with its state
            here.integrate(o)
            there.integrate(o)
        assert wait_until(lambda: there.local_edf(np.zeros(2)) is not None and there.isolated, timeout_s=60)
        for o in obs[2:]:
            here.integrate(o)
            there.integrate(o)
        assert len(there.snapshot().objects) == len(here.snapshot().objects) >= 1
        np.testing.assert_array_equal(there.occupied_points(), here.occupied_points())
        # equal to rounding: the EDF's exact box distances sum in BLAS, whose threads differ between processes
        np.testing.assert_allclose(there.local_edf(np.zeros(2)).values, here.local_edf(np.zeros(2)).values,
                                   rtol=0.0, atol=1e-9)
        assert set(there.timings_ms) == set(here.timings_ms)
    finally:
        back = there.close()
    assert isinstance(back, ObjectMapper) and len(back.snapshot().objects) == len(here.snapshot().objects)


def test_change_evidence_from_localization_reaches_the_map_in_the_worker(observations):
    """Live, localization hands the objects it found off their surfaces to the isolated map: the worker's map takes
    the same forced outlier as the map here would."""
    robot, obs = observations
    here, there = ObjectMapper(robot, MappingParams()), MapProcess(ObjectMapper(robot, MappingParams()))
    try:
        assert wait_until(lambda: there.local_edf(np.zeros(2)) is not None and there.isolated, timeout_s=60)
        for o in obs[:3]:
            here.integrate(o)
            there.integrate(o)
        ids = tuple(o.id for o in here.snapshot().objects)
        assert ids
        here.note_change_evidence(ids)
        there.note_change_evidence(ids)
        here.integrate(obs[3])
        there.integrate(obs[3])
        mine = {o.id: o.consistency for o in here.snapshot().objects}
        theirs = {o.id: o.consistency for o in there.snapshot().objects}
        assert theirs == pytest.approx(mine)
        untouched = ObjectMapper(robot, MappingParams())
        for o in obs:
            untouched.integrate(o)
        before = {o.id: o.consistency for o in untouched.snapshot().objects}
        assert any(theirs[i] < before[i] for i in ids if i in theirs and i in before) or set(ids) - set(theirs)
    finally:
        there.close()


def test_a_failing_or_dead_worker_raises_map_process_errors(observations):
    robot, obs = observations
    there = MapProcess(ObjectMapper(robot, MappingParams()))
    assert wait_until(lambda: there.local_edf(np.zeros(2)) is not None and there.isolated, timeout_s=60)
    there.integrate(obs[0])
    with pytest.raises(MapProcessError, match="integrate failed in the mapping process: AttributeError"):
        there.integrate(replace(obs[1], frames=("not a depth frame",)))
    os.kill(there.pid, signal.SIGKILL)
    with pytest.raises(MapProcessError, match="gone"):
        there.integrate(obs[1])
    assert there.close() is None


def test_a_reset_hands_the_running_worker_a_new_map(observations):
    robot, obs = observations
    there = MapProcess(ObjectMapper(robot, MappingParams()))
    try:
        assert wait_until(lambda: there.local_edf(np.zeros(2)) is not None and there.isolated, timeout_s=60)
        there.integrate(obs[0])
        assert there.snapshot().objects
        pid = there.pid
        there.adopt(ObjectMapper(robot, MappingParams()))
        assert there.pid == pid and there.alive and not there.snapshot().objects
        there.integrate(obs[1])
        assert there.snapshot().objects
    finally:
        there.close(keep=False)
    assert not there.alive
    with pytest.raises(MapProcessError, match="closed"):
        there.adopt(ObjectMapper(robot, MappingParams()))
