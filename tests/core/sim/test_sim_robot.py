"""SimRobot behind the RobotBackend protocol."""

import numpy as np
import pytest

from core.scene import Box, Scene
from core.sim.sim_robot import SimRobot
from core.types import Observation, RobotBackend


def _drive_forward(backend: RobotBackend, speed_mps: float, t: float) -> Observation:
    """What the runtime does with any backend: command a base velocity, then observe."""
    backend.command(np.array([speed_mps, 0, 0, 0, 0, 0, 0, 0, 0]), t)
    return backend.observe()


def test_moves_and_reports_through_the_backend_protocol(world):
    robot = SimRobot(world, cameras=())
    first = _drive_forward(robot, 0.5, 0.0)
    robot.step(0.3)
    obs = _drive_forward(robot, 0.5, robot.time)
    assert obs.state.t == pytest.approx(first.state.t + 0.3)
    assert obs.state.q[0] > first.state.q[0] + 0.05 and obs.state.v[0] > 0.4
    assert obs.odometry is not None and obs.odometry.pose[0] > 0.05  # the simulation reports odometry
    robot.close()


def test_frames_at_camera_rate(world):
    world.load_scene(Scene((Box("a", (2.0, 0.0, 0.3)),)))
    robot = SimRobot(world)
    for _ in range(100):
        robot.command(np.zeros(9), robot.time)
        robot.step(0.01)
    obs = robot.observe()
    by_camera = {c: [f for f in obs.frames if f.camera == c] for c in ("hand", "base")}
    assert 10 <= len(by_camera["hand"]) <= 11 and 10 <= len(by_camera["base"]) <= 11
    stamps = [f.t for f in by_camera["base"]]
    np.testing.assert_allclose(np.diff(stamps), 0.1, atol=0.003)
    assert robot.observe().frames == ()
    assert obs.frames[0].depth.shape == (240, 320)
    robot.close()


def test_stale_command_stops_the_robot(world):
    robot = SimRobot(world, cameras=())
    robot.command(np.array([0.5, 0, 0, 0, 0, 0, 0, 0, 0]), 0.0)
    robot.step(0.3)
    assert robot.observe().state.v[0] > 0.4
    robot.step(1.0)  # no new command for longer than the timeout
    assert abs(robot.observe().state.v[0]) < 0.02


def test_bad_command_counted_and_stops(world):
    robot = SimRobot(world, cameras=())
    robot.command(np.array([0.5, 0, 0, 0, 0, 0, 0, 0, 0]), 0.0)
    robot.step(0.3)
    robot.command(np.array([np.nan] * 9), 0.3)
    robot.command(np.zeros(4), 0.3)
    robot.step(0.3)
    assert robot.rejected_commands == 2
    assert abs(robot.observe().state.v[0]) < 0.02
