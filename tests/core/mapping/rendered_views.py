"""Rendering real MuJoCo depth frames for the mapping tests: a world, its cameras, observations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from core.params import CameraParams, SensorParams, SimParams
from core.robot.model import READY_Q, RobotModel
from core.scene import Box, Scene
from core.sim.depth_camera import DepthCamera
from core.sim.world import SimWorld
from core.types import DepthFrame, Observation


class View:
    """A world with boxes, the robot at a pose, and depth cameras rendering `Observation`s at the true pose.

    The cameras' image effects are `sensor`'s (default: exact depth with `noise_std_m` · z² noise)."""

    def __init__(self, robot: RobotModel, boxes: tuple[Box, ...], cameras: tuple[str, ...] = ("hand", "base"),
                 noise_std_m: float = 0.0, q: np.ndarray | None = None, seed: int = 0,
                 sensor: SensorParams | None = None) -> None:
        self.world = SimWorld(robot, SimParams(), Scene(boxes))
        self.world.set_robot(READY_Q if q is None else q)
        sensor = sensor or replace(SensorParams.ideal(), depth_noise_m=noise_std_m)
        self.cameras = [DepthCamera(self.world, name, CameraParams(), seed=seed + i, sensor=sensor)
                        for i, name in enumerate(cameras)]
        self.frames = 0

    def frame_set(self) -> tuple[DepthFrame, ...]:
        return tuple(c.render() for c in self.cameras)

    def observe(self, dt: float = 0.1, camera: DepthCamera | None = None) -> Observation:
        """Render every camera (or only `camera`) now, then advance the frame clock by dt (the sim does not step)."""
        self.world.data.time += dt
        self.frames += 1
        frames = self.frame_set() if camera is None else (camera.render(),)
        return Observation(state=self.world.state(), frames=frames, odometry=None)

    def close(self) -> None:
        for c in self.cameras:
            c.close()


def yaw_of(pose: np.ndarray) -> float:
    return float(np.arctan2(pose[1, 0], pose[0, 0]))


def yaw_error(a: float, b: float, period: float = np.pi / 2) -> float:
    """Smallest difference of two box yaws (a box's yaw is defined modulo 90°)."""
    d = (a - b) % period
    return float(min(d, period - d))
