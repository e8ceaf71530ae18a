"""`StateHistory`: the robot's recent joint states, to ask where it was when a depth frame was exposed.

A depth frame shows the world at its exposure, which precedes its stamp by the camera's latency and the
map's integration by the perception delay; the robot has moved meanwhile (docs/design.md, "One depth
frame: camera → map → EDF"). Linear interpolation between the control loop's states (100 Hz) is exact to well under a
millimetre at the base's and arm's speeds; the yaw q[2] is interpolated the short way round.
"""

from __future__ import annotations

import bisect
import math
from collections import deque

from core.types import RobotState

YAW = 2
"""Index of the base yaw in q (an angle: interpolated the short way round)."""


class StateHistory:
    """States of the last `horizon_s` seconds (robot time), oldest first; `at(t)` interpolates."""

    def __init__(self, horizon_s: float = 2.0) -> None:
        self.horizon_s = horizon_s
        self._states: deque[RobotState] = deque()
        self._times: deque[float] = deque()

    def __len__(self) -> int:
        return len(self._states)

    def append(self, state: RobotState) -> None:
        """Add a state; one older than the newest (a new scene, a reset clock) starts the history afresh."""
        if self._times and state.t < self._times[-1]:
            self.clear()
        if self._times and state.t == self._times[-1]:
            self._states[-1] = state
            return
        self._states.append(state)
        self._times.append(state.t)
        while self._times[-1] - self._times[0] > self.horizon_s and len(self._times) > 2:
            self._states.popleft()
            self._times.popleft()

    def clear(self) -> None:
        self._states.clear()
        self._times.clear()

    def at(self, t: float) -> RobotState | None:
        """The state at time t: interpolated inside the history, moved at constant velocity from its end
        outside it; None when the history is empty."""
        if not self._states:
            return None
        i = bisect.bisect_right(self._times, t)
        if i == 0 or i == len(self._states):
            nearest = self._states[0] if i == 0 else self._states[-1]
            return RobotState(t, nearest.q + nearest.v * (t - nearest.t), nearest.v.copy())
        a, b = self._states[i - 1], self._states[i]
        alpha = (t - a.t) / (b.t - a.t)
        dq = b.q - a.q
        dq[YAW] = math.remainder(dq[YAW], 2 * math.pi)
        return RobotState(t, a.q + alpha * dq, a.v + alpha * (b.v - a.v))
