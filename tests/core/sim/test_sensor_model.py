"""The sensor model (`SensorParams`), measured: each effect on frames rendered by the MuJoCo cameras, or on
the odometry of the simulated robot driving in MuJoCo."""

import math
from dataclasses import replace

import numpy as np
import pytest

from core.mapping.depth_points import unproject
from core.params import CameraParams, SensorParams, SimParams
from core.robot.model import READY_Q
from core.scene import Box, Scene
from core.sim.depth_camera import DepthCamera
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld

IDEAL = SensorParams.ideal()
WALL = Box("wall", (3.6, 0.0, 1.5), (0.2, 8.0, 3.0))
"""A wall 3 m ahead of the base camera (face at x = 3.5 m), filling its image above the floor."""


def _pair(world: SimWorld, sensor: SensorParams, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(exact, sensed) depth of the base camera, rendered from the same scene."""
    exact = DepthCamera(world, "base", CameraParams(range_m=5.0))
    sensed = DepthCamera(world, "base", CameraParams(range_m=5.0), seed=seed, sensor=sensor)
    out = exact.render().depth.astype(float), sensed.render().depth.astype(float)
    exact.close()
    sensed.close()
    return out


@pytest.fixture
def walled(robot) -> SimWorld:
    world = SimWorld(robot, SimParams(sensor=IDEAL), Scene((WALL,)))
    world.set_robot(READY_Q)
    return world


def test_defaults_are_on_and_ideal_is_exact():
    on, off = SensorParams(), SensorParams.ideal()
    assert on.depth_noise_m > 0 and on.dropout_fraction > 0 and on.flying_pixel_fraction > 0
    assert on.odometry_drift_m > 0 and on.odometry_drift_rad > 0 and on.camera_time_offset_s > 0
    assert off.depth_noise_m == off.dropout_fraction == off.flying_pixel_fraction == 0.0
    assert off.odometry_drift_m == off.odometry_drift_rad == off.camera_time_offset_s == 0.0
    assert SimParams().sensor == on  # a simulated robot perceives as a real one unless told otherwise


def test_depth_noise_grows_with_depth_squared(walled):
    coeff = SensorParams().depth_noise_m
    exact, noisy = _pair(walled, replace(IDEAL, depth_noise_m=coeff), seed=3)
    both = (exact > 0) & (noisy > 0)
    z, err = exact[both], noisy[both] - exact[both]
    stds = []
    for lo, hi in ((0.8, 1.2), (1.8, 2.2), (2.7, 3.1)):
        band = (z > lo) & (z < hi)
        assert band.sum() > 1000
        stds.append(err[band].std())
        assert err[band].std() / np.mean(z[band] ** 2) == pytest.approx(coeff, rel=0.1)
    assert stds[2] / stds[0] == pytest.approx(2.9**2, rel=0.15)  # z², not z


def test_random_dropouts_remove_their_fraction_of_the_returns(walled):
    fraction = SensorParams().dropout_fraction
    exact, sensed = _pair(walled, replace(IDEAL, dropout_fraction=fraction), seed=5)
    lost = (exact > 0) & (sensed == 0)
    assert lost.sum() / (exact > 0).sum() == pytest.approx(fraction, rel=0.1)
    rows = lost.mean(axis=1)[(exact > 0).all(axis=1)]
    assert rows.std() < 3 * math.sqrt(fraction / exact.shape[1])  # spread evenly, not in bands


def test_a_dark_box_returns_nothing_and_still_hides_what_is_behind_it(robot, walled):
    walled.add_box(Box("dark", (1.8, 0.0, 0.3), dark=True))
    cam = DepthCamera(walled, "base", CameraParams(range_m=5.0), sensor=IDEAL)
    ids = cam.render_box_ids()
    depth = cam.render().depth
    cam.close()
    on_box = ids == "dark"
    assert on_box.sum() > 2000
    assert np.all(depth[on_box] == 0.0)  # not the wall's 3 m behind it
    assert np.all(depth[ids == "wall"] > 2.5)
    walled.add_box(Box("plain", (1.8, -1.0, 0.3)))  # the same box, not dark, returns everywhere
    cam = DepthCamera(walled, "base", CameraParams(range_m=5.0), sensor=IDEAL)
    ids, depth = cam.render_box_ids(), cam.render().depth
    cam.close()
    assert np.all(depth[ids == "plain"] > 0.5)


def test_flying_pixels_hang_between_the_two_sides_of_depth_edges(walled):
    walled.add_box(Box("front", (1.8, 0.0, 0.3)))
    sensor = replace(IDEAL, flying_pixel_fraction=SensorParams().flying_pixel_fraction)
    exact, sensed = _pair(walled, sensor, seed=2)
    jump = sensor.flying_pixel_jump_m
    # edge pairs of the exact image (both sides returning) and the pixels on them
    edge = np.zeros(exact.shape, bool)
    pairs = 0
    for a, b, sl_a, sl_b in ((exact[:-1], exact[1:], np.s_[:-1], np.s_[1:]),
                             (exact[:, :-1], exact[:, 1:], np.s_[:, :-1], np.s_[:, 1:])):
        e = (np.abs(a - b) > jump) & (a > 0) & (b > 0)
        pairs += int(e.sum())
        edge[sl_a] |= e
        edge[sl_b] |= e
    moved = np.abs(sensed - exact) > 1e-6
    assert pairs > 100
    assert moved.sum() > 0 and not np.any(moved & ~edge)  # only pixels at edges fly
    padded = np.pad(exact, 1, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, (3, 3))
    lo, hi = windows.min(axis=(2, 3)), windows.max(axis=(2, 3))
    assert np.all((sensed[moved] >= lo[moved]) & (sensed[moved] <= hi[moved]))  # between the two sides
    assert np.median(np.minimum(sensed - lo, hi - sensed)[moved]) > 0.1  # hanging in free space, not on a side
    assert moved.sum() == pytest.approx(sensor.flying_pixel_fraction * pairs, rel=0.25)  # pairs sharing a pixel


def _drive(world: SimWorld, seed: int, qdot: np.ndarray, seconds: float) -> tuple[SimRobot, list]:
    """From the ready pose, command qdot for `seconds`: (robot, [(distance, angle, estimate error)] per 0.1 s)."""
    world.set_robot(READY_Q)
    sim = SimRobot(world, seed=seed, cameras=())
    errors = []
    for _ in range(int(round(seconds * 10))):
        sim.command(qdot, sim.time)
        sim.step(0.1)
        errors.append((sim.odometry_estimate.distance_m, sim.odometry_estimate.turned_rad,
                       sim.odometry_estimate.error.copy()))
    return sim, errors


def test_odometry_drift_is_a_random_walk_per_metre_driven(robot):
    drift = SensorParams().odometry_drift_m
    world = SimWorld(robot, SimParams(sensor=replace(IDEAL, odometry_drift_m=drift)))
    forward = np.zeros(9)
    forward[0] = 1.0
    at = {1.0: [], 4.0: []}
    for seed in range(30):
        _, errors = _drive(world, seed, forward, 4.2)
        for dist in at:
            k = next(i for i, e in enumerate(errors) if e[0] >= dist)
            at[dist].append(errors[k][2][:2] / math.sqrt(errors[k][0]))
    for dist, e in at.items():
        # error per √metre has the configured std on each axis, whatever the distance
        assert np.std(np.array(e)) == pytest.approx(drift, rel=0.3), dist


def test_heading_drift_is_a_random_walk_per_radian_turned(robot):
    drift = SensorParams().odometry_drift_rad
    world = SimWorld(robot, SimParams(sensor=replace(IDEAL, odometry_drift_rad=drift)))
    turn = np.zeros(9)
    turn[2] = 0.75
    finals = []
    for seed in range(30):
        _, errors = _drive(world, seed, turn, 4.0)
        dist, turned, e = errors[-1]
        assert dist < 1e-3 and turned == pytest.approx(3.0, abs=0.1)
        finals.append(e[2] / math.sqrt(turned))
    assert np.std(finals) == pytest.approx(drift, rel=0.3)


def test_the_robot_reports_and_is_commanded_in_the_world_it_believes_in(robot):
    world = SimWorld(robot, SimParams(sensor=replace(IDEAL, odometry_drift_m=0.05, odometry_drift_rad=0.05)))
    turn = np.zeros(9)
    turn[2] = 0.75
    sim, _ = _drive(world, 1, turn, 3.0)
    e = sim.odometry_estimate.error
    assert abs(e[2]) > 1e-3
    obs = sim.observe()
    assert obs.state.q[:3] == pytest.approx(sim.true_state().q[:3] + e, abs=1e-9)
    # +x in the believed world: the true base moves along the believed x turned back by the heading error
    forward = np.zeros(9)
    forward[0] = 0.5
    before = sim.true_state().q[:2].copy()
    for _ in range(10):
        sim.command(forward, sim.time)
        sim.step(0.1)
    moved = sim.true_state().q[:2] - before
    assert math.atan2(moved[1], moved[0]) == pytest.approx(-e[2], abs=0.2 * abs(e[2]) + 1e-3)
    sim.world.set_robot(READY_Q)  # a teleport restarts the estimate at the truth
    assert sim.observe().state.q[:3] == pytest.approx(READY_Q[:3])


def test_frames_are_stamped_late_by_the_offset_and_misplaced_by_the_motion_meanwhile(robot):
    offset = SensorParams().camera_time_offset_s
    pole = Box("pole", (2.0, 0.0, 0.6), (0.1, 0.1, 1.2))
    world = SimWorld(robot, SimParams(sensor=replace(IDEAL, camera_time_offset_s=offset)), Scene((pole,)))
    q = READY_Q.copy()
    q[2] = -0.3
    world.set_robot(q)
    sim = SimRobot(world, cameras=("base",))
    turn = np.zeros(9)
    turn[2] = 0.75
    bearings, stamps = [], []
    for _ in range(8):
        sim.command(turn, sim.time)
        sim.step(0.1)
        for f in sim.observe().frames:
            stamps.append(f.t)
            pts = unproject(f.depth, f.K, f.T_world_camera)
            pts = pts[(pts[:, 2] > 0.15) & (np.hypot(pts[:, 0], pts[:, 1]) < 2.5)]  # the pole, not the floor
            if len(pts) > 50:
                bearings.append(float(np.mean(np.arctan2(pts[:, 1], pts[:, 0]))))  # truth: 0 from the base centre
    frac = (np.array(stamps[1:]) * 10) % 1  # (the first image is taken at the first physics step)
    assert frac == pytest.approx(np.full(len(frac), offset * 10), abs=1e-6)  # taken at k/10, stamped + offset
    # the pole appears turned on by yaw rate × offset (the pose is that of the stamp, the image older)
    assert len(bearings) >= 4
    assert np.median(bearings) == pytest.approx(0.75 * offset, abs=0.003)
