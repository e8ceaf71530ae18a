"""Camera latency compensated (`at_exposure`): a frame stamped late, at the pose of its stamp, is put back
at the pose of its exposure; measured on MuJoCo frames of a pole while the base turns. `frames_at_exposure`
does it for a batch from the state history, with the latency `camera_latency` chooses."""

from dataclasses import replace

import numpy as np
import pytest

from core.mapping.depth_points import unproject
from core.mapping.frame_exposure import at_exposure, camera_latency, frames_at_exposure
from core.params import SensorParams, SimParams
from core.robot.model import READY_Q
from core.robot.state_history import StateHistory
from core.scene import Box, Scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld

LATENCY_S = 0.05
YAW_RATE = 0.75


def _pole_bearing(frame) -> float | None:
    """Mean bearing of the pole's points from the base centre (truth: 0)."""
    pts = unproject(frame.depth, frame.K, frame.T_world_camera)
    pts = pts[(pts[:, 2] > 0.15) & (np.hypot(pts[:, 0], pts[:, 1]) < 2.5)]
    return float(np.mean(np.arctan2(pts[:, 1], pts[:, 0]))) if len(pts) > 50 else None


@pytest.fixture
def turning(robot):
    """(frames, history) of the base camera while the base turns past a pole 2 m ahead; frames stamped
    LATENCY_S late; states every 10 ms, as the closed loop observes them."""
    pole = Box("pole", (2.0, 0.0, 0.6), (0.1, 0.1, 1.2))
    sensor = replace(SensorParams.ideal(), camera_time_offset_s=LATENCY_S)
    world = SimWorld(robot, SimParams(sensor=sensor), Scene((pole,)))
    q = READY_Q.copy()
    q[2] = -0.3
    world.set_robot(q)
    sim = SimRobot(world, cameras=("base",))
    turn = np.zeros(9)
    turn[2] = YAW_RATE
    history, frames = StateHistory(), []
    for _ in range(80):
        sim.command(turn, sim.time)
        sim.step(0.01)
        obs = sim.observe()
        history.append(obs.state)
        frames.extend(obs.frames)
    sim.close()
    return frames, history


def test_a_late_frame_is_put_back_where_the_camera_was_at_exposure(robot, turning):
    frames, history = turning
    late, fixed = [], []
    for f in frames[1:]:
        moved = at_exposure(f, LATENCY_S, history.at(f.t), history.at(f.t - LATENCY_S), robot)
        assert moved.t == pytest.approx(f.t - LATENCY_S)
        for out, frame in ((late, f), (fixed, moved)):
            bearing = _pole_bearing(frame)
            if bearing is not None:
                out.append(bearing)
    assert len(fixed) >= 4
    assert np.median(late) == pytest.approx(YAW_RATE * LATENCY_S, abs=0.005)  # 37 mrad: 7 cm at 2 m
    assert abs(np.median(fixed)) < 0.003


def test_no_latency_or_an_unknown_camera_leaves_the_pose_alone(robot, turning):
    frames, history = turning
    f = frames[-1]
    assert at_exposure(f, 0.0, history.at(f.t), history.at(f.t), robot) is f
    other = replace(f, camera="thermal")
    moved = at_exposure(other, LATENCY_S, history.at(f.t), history.at(f.t - LATENCY_S), robot)
    assert moved.t == pytest.approx(f.t - LATENCY_S) and np.array_equal(moved.T_world_camera, f.T_world_camera)


def test_a_batch_is_moved_frame_by_frame_from_the_history(robot, turning):
    frames, history = turning
    moved = frames_at_exposure(frames[-3:], history, LATENCY_S, robot)
    assert isinstance(moved, tuple) and len(moved) == 3
    for f, m in zip(frames[-3:], moved, strict=True):
        expected = at_exposure(f, LATENCY_S, history.at(f.t), history.at(f.t - LATENCY_S), robot)
        assert m.t == expected.t and np.array_equal(m.T_world_camera, expected.T_world_camera)
    unplaced = frames_at_exposure(frames[-3:], StateHistory(), LATENCY_S, robot)  # no states yet: as stamped
    assert all(m is f for f, m in zip(frames[-3:], unplaced, strict=True))


def test_the_calibrated_latency_wins_over_the_declared_one():
    assert camera_latency(None, 0.02) == 0.02
    assert camera_latency(0.05, 0.02) == 0.05
    assert camera_latency(0.0, 0.02) == 0.0  # calibrated to none: compensation off
