"""The IPOPT reference solves the same problem: for one task, our Gauss-Newton SQP iterated to
convergence reaches IPOPT's optimum of J + J_aux (eqs. 5, 8, the dynamics and the bounds, with exact FK
and SO(3) log in the NLP and linearised ones in our QPs)."""

import numpy as np
import pinocchio as pin
import pytest

from core.htmpc import HTMPC
from core.htmpc.ipopt_reference import IpoptReference
from core.params import HTMPCParams
from core.types import BaseReference, EEReference, References
from tests.core.htmpc.conftest import lockstep, ready_state

PARAMS = HTMPCParams(sqp_iters_on_switch=40, sqp_step_tol=1e-6)
"""Iterated to convergence in the cost; the directions only J_aux holds converge slowly under the
Levenberg-Marquardt damping, but they barely change the cost."""
TURNED = pin.utils.rpyToMatrix(0.0, np.pi / 2, 0.4)
CASES = {
    "ee within reach": References(order=("ee",), ee=EEReference(np.array([[1.0, 0.3, 0.8]]), TURNED[None])),
    "ee out of reach": References(order=("ee",), ee=EEReference(np.array([[1.6, 0.3, 0.8]]), TURNED[None])),
    "base pose": References(order=("base",), base=BaseReference(np.array([[-0.4, 0.2]]), np.array([0.3]))),
    "base position": References(order=("base",), base=BaseReference(np.array([[-0.4, 0.2]]))),
    "arm posture": References(order=("posture",), posture=np.array([[0.5, -1.3, 1.9, 0.1, 1.2, 2.9]])),
    "ee in the base frame": References(order=("ee",), ee=EEReference(np.array([[0.7, 0.4, 0.9]]), TURNED[None],
                                                                     "base")),
}


STARTS = {"ee in the base frame": (0.5, -0.3, 0.7)}
"""The base away from the origin, so the base frame is not the world frame."""


@pytest.fixture(scope="module")
def reference(robot):
    return IpoptReference(robot, PARAMS)


@pytest.mark.parametrize("case", list(CASES))
def test_converged_sqp_reaches_ipopts_optimum(robot, reference, case):
    refs = CASES[case]
    controller = lockstep(HTMPC(robot, PARAMS))
    state = ready_state(base=STARTS.get(case, (0.0, 0.0, 0.0)))
    warm = controller.warm_start(state)
    controller.solve(state, refs, None)
    result = reference.solve(state, refs, None, warm.q, warm.v, warm.a, compare=controller.last_step.level_solutions)
    assert result.success
    ours, ipopt = result.compared_objectives[0], result.level_objectives[0]
    assert ours == pytest.approx(ipopt, rel=2e-3)
    assert ours >= ipopt * (1 - 1e-4)  # IPOPT's is the optimum (to its tolerance)
