import numpy as np

import core.sim  # noqa: F401  (GL backend before mujoco)
from core.htmpc import HTMPC
from core.robot.model import READY_Q
from core.types import RobotState


def lockstep(controller: HTMPC) -> HTMPC:
    """Simulated time waits for the solver (as in the runtime's lockstep mode): no wall-clock time-out,
    so a busy machine cannot turn a test's plan into a braking plan."""
    controller.enforce_timeout = False
    return controller


def ready_state(t: float = 0.0, base=(0.0, 0.0, 0.0)) -> RobotState:
    q = READY_Q.copy()
    q[:3] = base
    return RobotState(t, q, np.zeros(9))
