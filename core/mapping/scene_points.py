"""The points both maps build from: per depth frame, the world points that are neither floor nor robot.

Depth → points (`depth_points`), floor removal (`floor`), robot self-filter (`self_filter`), in that
order, for every frame of an `Observation`; the robot's spheres are placed once per observation.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np

from core.mapping.depth_points import unproject_frame
from core.mapping.floor import above_floor, floor_threshold
from core.mapping.self_filter import SelfFilter, outside_spheres
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import DepthFrame, Observation


class ScenePoints:
    """Non-floor, non-robot points of each frame (every `pixel_stride`-th pixel, within range)."""

    def __init__(self, robot: RobotModel, params: MappingParams) -> None:
        self.params = params
        self.self_filter = SelfFilter(robot, params.self_filter_margin_m)

    def of_frame(self, frame: DepthFrame, spheres: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """World points (N×3) of one frame without floor and robot (spheres from `SelfFilter.spheres`)."""
        p = self.params
        fp = unproject_frame(frame.depth, frame.K, frame.T_world_camera, p.pixel_stride,
                             min(p.range_m, frame.range_m))
        keep = above_floor(fp.points, floor_threshold(fp.depth, fp.ray_dz, p.floor_height_m, p.depth_noise_coeff_m))
        pts = fp.points[keep]
        return pts[outside_spheres(pts, *spheres)]

    def each(self, obs: Observation, timings: dict[str, float]) -> Iterator[tuple[DepthFrame, np.ndarray]]:
        """(frame, points) for every frame of `obs`; the time spent is added to timings['points'] (ms)."""
        spheres = self.self_filter.spheres(obs.state.q)
        for frame in obs.frames:
            t0 = time.perf_counter()
            points = self.of_frame(frame, spheres)
            timings["points"] = timings.get("points", 0.0) + (time.perf_counter() - t0) * 1e3
            yield frame, points


def latest_time(t: float, obs: Observation) -> float:
    """The newest of t, the observation's state time and its frames' times."""
    return max(t, obs.state.t, *(f.t for f in obs.frames))
