"""`StateHistory`: the robot's state at any recent time, interpolated between the loop's states."""

import math

import numpy as np
import pytest

from core.robot.state_history import StateHistory
from core.types import RobotState


def _state(t: float, yaw: float = 0.0, x: float = 0.0, vx: float = 0.0) -> RobotState:
    q, v = np.zeros(9), np.zeros(9)
    q[0], q[2], v[0] = x, yaw, vx
    return RobotState(t, q, v)


def test_interpolates_between_states_and_extrapolates_at_constant_velocity_outside():
    h = StateHistory()
    assert h.at(0.0) is None
    h.append(_state(0.0, x=0.0, vx=1.0))
    h.append(_state(0.1, x=0.1, vx=1.0))
    assert h.at(0.04).q[0] == pytest.approx(0.04)
    assert h.at(0.15).q[0] == pytest.approx(0.15)  # newer than the newest: moved on at its velocity
    assert h.at(-0.05).q[0] == pytest.approx(-0.05)
    assert h.at(0.04).t == 0.04


def test_yaw_is_interpolated_the_short_way_round():
    h = StateHistory()
    h.append(_state(0.0, yaw=math.pi - 0.05))
    h.append(_state(0.1, yaw=-math.pi + 0.05))
    yaw = h.at(0.05).q[2]
    assert math.remainder(yaw - math.pi, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_keeps_only_the_horizon_and_restarts_when_time_goes_back():
    h = StateHistory(horizon_s=1.0)
    for k in range(300):
        h.append(_state(0.01 * k, x=0.01 * k))
    assert 100 <= len(h) <= 102
    assert h.at(2.5).q[0] == pytest.approx(2.5)
    h.append(_state(0.0))  # a new scene's clock
    assert len(h) == 1 and h.at(0.0).q[0] == 0.0
