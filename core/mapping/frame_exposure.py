"""A depth frame moved back to its exposure: the camera's latency compensated.

A driver stamps a frame some time after the camera exposed it (`camera_latency_s`, calibrated, e.g. by a
hand–eye time-offset estimate) and gives it the camera pose the robot estimated at the stamp. While the
base turns or the arm swings, that pose is off by the motion in between, and every wall is smeared
across the map. The frame is given back its exposure time and the camera pose of the robot's state
then: T_world_camera(exposure) = T(q_exposure) · T(q_stamp)⁻¹ · T_world_camera(stamp), which keeps
any extrinsic calibration in the frame's own pose and corrects only the motion.

The latency is the calibrated one (`MappingParams.camera_latency_s`) when it is set, else the one the robot
backend declares (`BackendAbilities.camera_latency_s`: the simulated camera's exact offset, 0 for a real
robot): `camera_latency`. `frames_at_exposure` moves a batch of frames back, the robot's states read from
its recent history (`StateHistory`); the closed loop calls it on every frame before the map gets it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from core.robot.model import RobotModel
from core.robot.state_history import StateHistory
from core.types import DepthFrame, RobotState


def camera_latency(calibrated_s: float | None, declared_s: float) -> float:
    """The exposure-to-stamp latency to compensate: `calibrated_s` (`MappingParams.camera_latency_s`) when
    set, else `declared_s`, what the backend knows (`BackendAbilities.camera_latency_s`)."""
    return calibrated_s if calibrated_s is not None else declared_s


def frames_at_exposure(frames: Iterable[DepthFrame], history: StateHistory, latency_s: float,
                       robot: RobotModel) -> tuple[DepthFrame, ...]:
    """Each frame moved back to its exposure (`at_exposure`), with the robot's states at its stamp and at its
    exposure from `history`; with no state in the history yet, the frames stay as stamped."""
    moved = []
    for frame in frames:
        stamp, exposure = history.at(frame.t), history.at(frame.t - latency_s)
        moved.append(frame if stamp is None or exposure is None
                     else at_exposure(frame, latency_s, stamp, exposure, robot))
    return tuple(moved)


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
