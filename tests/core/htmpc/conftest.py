import numpy as np
import pytest

import core.sim  # noqa: F401  (GL backend before mujoco)
from core.htmpc import HTMPC
from core.robot.model import READY_Q
from core.types import RobotState


@pytest.fixture(scope="module")
def controller(robot):
    return HTMPC(robot)


def ready_state(t: float = 0.0, base=(0.0, 0.0, 0.0)) -> RobotState:
    q = READY_Q.copy()
    q[:3] = base
    return RobotState(t, q, np.zeros(9))
