"""Depth cameras: known distances, poses equal to FK, range cut-off, noise, segmentation."""

import math
from dataclasses import replace

import numpy as np
import pytest

from core.params import CameraParams, SensorParams, SimParams
from core.robot.model import READY_Q
from core.scene import Box, Scene
from core.sim.depth_camera import DepthCamera
from core.sim.world import SimWorld


def _noise_only(coeff_m: float) -> SensorParams:
    return replace(SensorParams.ideal(), depth_noise_m=coeff_m)


def _wall_ahead(world: SimWorld, x_face: float) -> None:
    world.load_scene(Scene((Box("wall", (x_face + 0.1, 0.0, 1.0), (0.2, 4.0, 2.0)),)))


def test_camera_poses_agree_with_fk(world, robot):
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = robot.random_q(rng)
        world.set_robot(q)
        for name in ("hand", "base"):
            cam = world.model.camera(f"camera_{name}").id
            T = robot.camera_pose(q, name)
            np.testing.assert_allclose(world.data.cam_xpos[cam], T[:3, 3], atol=1e-9)
            R_mj = world.data.cam_xmat[cam].reshape(3, 3)
            np.testing.assert_allclose(R_mj @ np.diag([1, -1, -1]), T[:3, :3], atol=1e-9)


@pytest.mark.parametrize("name", ["hand", "base"])
def test_box_at_known_distance(world, robot, name):
    _wall_ahead(world, 2.0)
    world.set_robot(READY_Q)
    cam = DepthCamera(world, name, CameraParams())
    frame = cam.render()
    T = frame.T_world_camera
    # every pixel that sees the wall: its back-projected point lies on the plane x = 2.0
    v, u = np.nonzero(frame.depth > 0)
    z = frame.depth[v, u].astype(float)
    rays = np.linalg.inv(frame.K) @ np.vstack([u, v, np.ones_like(u)])
    pts = (T[:3, :3] @ (rays * z) + T[:3, 3:4]).T
    on_wall = (np.abs(pts[:, 0] - 2.0) < 0.05) & (pts[:, 2] > 0.05)  # not the floor at its foot
    assert on_wall.mean() > 0.3
    np.testing.assert_allclose(pts[on_wall, 0], 2.0, atol=0.01)
    # centre pixel: planar depth = distance to the plane along the optical axis
    axis = T[:3, 2]
    expected = (2.0 - T[0, 3]) / axis[0]
    centre = frame.depth[frame.depth.shape[0] // 2, frame.depth.shape[1] // 2]
    assert centre == pytest.approx(expected, abs=0.01)
    cam.close()


def test_range_cutoff_and_noise(robot):
    world = SimWorld(robot, SimParams())
    _wall_ahead(world, 2.0)
    world.set_robot(READY_Q)
    far = DepthCamera(world, "base", CameraParams(range_m=1.0))
    assert far.render().depth.max() <= 1.0
    noisy = DepthCamera(world, "base", CameraParams(), seed=4, sensor=_noise_only(0.01))
    clean = DepthCamera(world, "base", CameraParams())
    d_noisy, d_clean = noisy.render().depth, clean.render().depth
    both = (d_noisy > 0) & (d_clean > 0)
    residual = (d_noisy[both] - d_clean[both]) / d_clean[both] ** 2
    assert residual.std() == pytest.approx(0.01, rel=0.1)
    for c in (far, noisy, clean):
        c.close()


def test_intrinsics_follow_fov():
    params = CameraParams(width_px=320, height_px=240, fovy_deg=60.0)
    cam_K = __import__("core.sim.depth_camera", fromlist=["intrinsics"]).intrinsics(params)
    assert cam_K[1, 1] == pytest.approx(120 / math.tan(math.radians(30)))
    assert cam_K[0, 2] == pytest.approx(159.5) and cam_K[1, 2] == pytest.approx(119.5)


def test_ground_truth_segmentation(world):
    world.load_scene(Scene((Box("left", (2.0, 0.6, 0.3)), Box("right", (2.0, -0.6, 0.3)))))
    cam = DepthCamera(world, "base", CameraParams())
    ids = cam.render_box_ids()
    assert {"left", "right"} <= set(np.unique(ids))
    cols_left = np.nonzero((ids == "left").any(axis=0))[0]
    cols_right = np.nonzero((ids == "right").any(axis=0))[0]
    assert cols_left.mean() < cols_right.mean()  # +y is to the image's left
    cam.close()


def test_renderer_follows_recompile(robot):
    world = SimWorld(robot, SimParams(box_pool=1))
    world.set_robot(READY_Q)
    cam = DepthCamera(world, "base", CameraParams())
    assert (cam.render().depth[100:140, 150:170] == 0).any()
    world.add_box(Box("far", (8.0, 8.0, 0.3)))
    world.add_box(Box("front", (2.0, 0.0, 0.3)))  # grows the pool: a new model
    assert cam.render().depth[200, 160] > 0
    cam.close()


def test_noise_never_brings_far_pixels_into_range(robot):
    world = SimWorld(robot, SimParams())
    world.load_scene(Scene((Box("near", (1.8, 0.0, 0.3)),)))
    world.set_robot(READY_Q)
    clean = DepthCamera(world, "base", CameraParams()).render().depth
    noisy = DepthCamera(world, "base", CameraParams(), seed=1, sensor=_noise_only(0.05)).render().depth
    assert np.all(noisy[clean == 0] == 0)  # sky and far floor stay "no return"


def test_a_camera_renders_from_any_thread_with_the_renderers_it_made(world):
    """A render leaves no GL context current: renderers made on a thread that lives on render on another (EGL
    refused that: EGL_BAD_ACCESS), the same renderer objects, so a Reset's new physics thread makes none anew
    (each new one cost native memory that was never handed back, issue 32)."""
    import threading

    world.load_scene(Scene((Box("front", (2.0, 0.0, 0.3)),)))
    world.set_robot(READY_Q)
    cam = DepthCamera(world, "base", CameraParams())
    made, done = threading.Event(), threading.Event()
    depths: list[np.ndarray] = []

    def first_thread() -> None:
        depths.append(cam.render().depth)
        made.set()
        done.wait(30)  # alive while the other thread renders

    thread = threading.Thread(target=first_thread)
    thread.start()
    try:
        assert made.wait(60)
        renderer = cam._renderer
        depths.append(cam.render().depth)
        assert cam._renderer is renderer
    finally:
        done.set()
        thread.join()
    np.testing.assert_array_equal(depths[0], depths[1])
    cam.close()
