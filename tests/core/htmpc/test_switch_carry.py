"""A task switch's SQP iterations spread over its first steps (`HTMPCParams.sqp_switch_carry`): the first step makes
at most `sqp_iters_on_switch`, the carried ones follow at most that many a step, and a switch mid-carry starts
over. Counted in the plans (`extras['sqp_iterations']`); the plans' quality is the closed-loop tests' business."""

from __future__ import annotations

import numpy as np

from core.htmpc import HTMPC
from core.params import HTMPCParams
from core.types import EEReference, References
from tests.core.htmpc.conftest import lockstep, ready_state

EE = EEReference(position=np.array([[1.2, 0.5, 0.6]]))


def _iterations(controller: HTMPC, switches: list[bool]) -> list[int]:
    out = []
    for k, switched in enumerate(switches):
        plan = controller.solve(ready_state(0.1 * k), References(order=("ee",), ee=EE, switched=switched), None)
        out.append(int(plan.extras["sqp_iterations"]))
    return out


def test_the_switch_iterations_are_carried_to_the_next_steps(robot) -> None:
    params = HTMPCParams(sqp_iters_on_switch=2, sqp_switch_carry=3, sqp_step_tol=1e-9)
    its = _iterations(lockstep(HTMPC(robot, params)), [True, False, False, False, False])
    assert its == [2, 2, 1, 1, 1]


def test_a_new_switch_restarts_the_carry(robot) -> None:
    params = HTMPCParams(sqp_iters_on_switch=2, sqp_switch_carry=3, sqp_step_tol=1e-9)
    its = _iterations(lockstep(HTMPC(robot, params)), [True, False, True, False, False, False])
    assert its == [2, 2, 2, 2, 1, 1]


def test_no_carry_iterates_only_the_first_step(robot) -> None:
    params = HTMPCParams(sqp_iters_on_switch=5, sqp_switch_carry=0, sqp_step_tol=1e-9)
    assert _iterations(lockstep(HTMPC(robot, params)), [True, False, False]) == [5, 1, 1]
