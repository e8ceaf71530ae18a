"""`BridgeRobot`: the `RobotBackend` of a real robot whose driver is connected to the bridge.

The runtime drives it exactly as it drives `SimRobot`: `observe()` returns the driver's latest
accepted state, the depth frames that arrived since the previous call, the odometry (the base
part of the state when the driver sends none) and the state's `pose_source` (odometry, which the
runtime's localizer corrects when localization is on, or a pose the robot localized itself, used as
it is); `command(qdot, t)` sends a velocity command. Its `abilities` are a real robot's: it runs on
its own clock (no lockstep), there is no simulated world (no scene edits, no ground truth), and its
cameras' latency is for the operator to calibrate (`MappingParams.camera_latency_s`).

A command goes out as the runtime computed it only while everything is sound; otherwise zero velocity
goes out, with the reason: the command itself is not 9 finite numbers (`invalid_command`), the state is
older than the link's `stale_after_s` (`stale_state`), or the motion gate is shut: the server shuts it
unless the attached runtime is running (`emergency_stop` after an emergency stop, else `not_running`:
idle, paused, stopped, finished, failed; on hardware such a run must hold still). Zero commands of a
run that is not running carry that reason too, never `runtime`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from app.bridge.protocol import STATE_LIMIT, CommandReason
from app.bridge.robot_link import RobotLink, SentCommand
from core.types import NQ, BackendAbilities, Observation, Odometry, RobotState

log = logging.getLogger(__name__)


class BridgeRobot:
    """A robot behind the bridge: observations from its driver, commands to it."""

    abilities = BackendAbilities(steps_in_lockstep=False, simulated=False, camera_latency_s=0.0)
    """A real robot: real time, no simulated world, camera latency unknown here (calibrate it)."""

    def __init__(self, link: RobotLink) -> None:
        self.link = link
        self.motion_allowed: Callable[[], bool] = lambda: True
        self.halt_reason: Callable[[], CommandReason] = lambda: "not_running"
        """Why the runtime's commands may not move the robot while `motion_allowed()` is False."""
        self.rejected_commands = 0
        self._placeholder = RobotState(0.0, np.zeros(NQ), np.zeros(NQ))

    def wait_for_state(self, timeout_s: float) -> bool:
        """Block until the driver has sent a state (True) or `timeout_s` passed (False)."""
        deadline = time.monotonic() + timeout_s
        while self.link.state is None:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    def observe(self) -> Observation:
        """Latest state (all zeros at t = 0 before the driver's first), new frames, odometry, and what the base
        pose is (the driver's `pose_source`: odometry, or a pose the robot localized itself)."""
        state, frames, odometry, pose_source = self.link.take()
        state = state or self._placeholder
        if odometry is None:
            odometry = Odometry(state.t, state.q[:3].copy(), state.v[:3].copy())
        return Observation(state=state, frames=frames, odometry=odometry, pose_source=pose_source)

    def command(self, qdot: np.ndarray, t: float) -> None:
        """Send qdot[9] stamped t, or zero velocity when the command or the link is not sound."""
        self.send(qdot, t)

    def send(self, qdot: np.ndarray, t: float) -> SentCommand:
        """`command`, returning what was issued (seq, qdot, reason)."""
        qdot = np.asarray(qdot, dtype=float)
        reason = self._veto(qdot, t)
        if reason != "runtime":
            qdot = np.zeros(NQ)
            t = t if np.isfinite(t) else self.link.latest_t()
        return self.link.send_command(qdot, float(t), reason)

    def _veto(self, qdot: np.ndarray, t: float) -> CommandReason:
        if (qdot.shape != (NQ,) or not np.all(np.isfinite(qdot)) or np.any(np.abs(qdot) > STATE_LIMIT)
                or not np.isfinite(t)):
            self.rejected_commands += 1
            log.warning("refused command %r at t=%r: need 9 finite numbers; sending zero", qdot, t)
            return "invalid_command"
        if self.link.is_stale():
            return "stale_state"
        if not self.motion_allowed():
            return self.halt_reason()
        return "runtime"

    def stop(self) -> None:
        """Zero velocity now."""
        self.link.send_zero("shutdown")
