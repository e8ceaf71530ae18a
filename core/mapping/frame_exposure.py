"""A depth frame moved back to its exposure: the camera's latency compensated.

A driver stamps a frame some time after the camera exposed it (`camera_latency_s`, calibrated, e.g. by a
hand–eye time-offset estimate) and gives it the camera pose the robot estimated at the stamp. While the
base turns or the arm swings, that pose is off by the motion in between, and every wall is smeared
across the map. The frame is given back its exposure time and the camera pose of the robot's state
then: T_world_camera(exposure) = T(q_exposure) · T(q_stamp)⁻¹ · T_world_camera(stamp), which keeps
any extrinsic calibration in the frame's own pose and corrects only the motion.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from core.robot.model import RobotModel
from core.types import DepthFrame, RobotState


def at_exposure(frame: DepthFrame, latency_s: float, stamp_state: RobotState, exposure_state: RobotState,
                robot: RobotModel) -> DepthFrame:
    """`frame` stamped at its exposure (t − latency_s) with the camera pose of `exposure_state`, the
    robot's state then (`stamp_state` is its state at the stamp, where the frame's pose was taken)."""
    if latency_s == 0.0:
        return frame
    t = frame.t - latency_s
    name = f"camera_{frame.camera}"
    if not robot.has_frame(name):
        return replace(frame, t=t)
    T_exposure, T_stamp = (robot.frame_pose(s.q, name) for s in (exposure_state, stamp_state))
    return replace(frame, t=t, T_world_camera=T_exposure @ np.linalg.inv(T_stamp) @ frame.T_world_camera)
