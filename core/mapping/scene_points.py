"""The points both maps build from: per depth frame, the world points that are neither floor nor robot.

Flying pixels dropped (`flying_pixels`), depth → points (`depth_points`), floor removal (`floor`), robot
self-filter (`self_filter`), in that order, for every frame of an `Observation`. The robot's spheres are
placed where the robot was when the frame was taken, q − v (t_state − t_frame): a frame is up to a camera
period older than the state that comes with it, and the arm moving at 2 rad/s would otherwise leave
pieces of itself in the map.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np

from core.mapping.depth_points import unproject_frame
from core.mapping.floor import above_floor, floor_threshold
from core.mapping.flying_pixels import EdgeFilter, without_flying_pixels
from core.mapping.self_filter import RobotBody, SelfFilter
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import DepthFrame, Observation


class ScenePoints:
    """Non-floor, non-robot points of each frame (every `pixel_stride`-th pixel, within range)."""

    def __init__(self, robot: RobotModel, params: MappingParams) -> None:
        self.params = params
        self.self_filter = SelfFilter(robot, params.self_filter_margin_m)
        self.edges = EdgeFilter.of(params)

    def of_frame(self, frame: DepthFrame, body: RobotBody) -> np.ndarray:
        """World points (N×3) of one frame without floor and robot (its body from `SelfFilter.body`)."""
        p = self.params
        depth = without_flying_pixels(frame.depth, p.pixel_stride, self.edges)
        fp = unproject_frame(depth, frame.K, frame.T_world_camera, p.pixel_stride, min(p.range_m, frame.range_m))
        keep = above_floor(fp.points, floor_threshold(fp.depth, fp.ray_dz, p.floor_height_m, p.depth_noise_coeff_m))
        pts = fp.points[keep]
        return pts[body.outside(pts)]

    def each(self, obs: Observation, timings: dict[str, float]) -> Iterator[tuple[DepthFrame, np.ndarray]]:
        """(frame, points) for every frame of `obs`; the time spent is added to timings['points'] (ms)."""
        for frame in obs.frames:
            t0 = time.perf_counter()
            points = self.of_frame(frame, self.self_filter.body(obs.q_at(frame.t)))
            timings["points"] = timings.get("points", 0.0) + (time.perf_counter() - t0) * 1e3
            yield frame, points


def latest_time(t: float, obs: Observation) -> float:
    """The newest of t, the observation's state time and its frames' times."""
    return max(t, obs.state.t, *(f.t for f in obs.frames))
