"""The lexicographic property (eq. 7) with conflicting base and EE goals."""

import numpy as np
import pytest

from core.htmpc import HTMPC
from core.params import HTMPCParams
from core.types import BaseReference, EEReference, References
from tests.core.htmpc.conftest import lockstep, ready_state

# The EE goal lies 2.2 m ahead while the base is asked to stay at the origin: they conflict
# (the UR10 reaches about 1.3 m), so whichever task comes first wins.
BASE = BaseReference(xy=np.zeros((1, 2)), yaw=np.zeros(1))
EE = EEReference(position=np.array([[2.2, 0.0, 0.9]]))


def converged_errors(robot, params: HTMPCParams, order: tuple[str, ...]) -> tuple[float, float, HTMPC]:
    """Repeated SQP iterations at the same state: the linearised optimum of each level."""
    c = lockstep(HTMPC(robot, params))
    refs = References(order=order, base=BASE if "base" in order else None, ee=EE if "ee" in order else None,
                      switched=True)
    c.solve(ready_state(), refs, None)
    step = c.last_step
    errs = {}
    for name in order:
        e = step.lins[name].e0[1:] + np.einsum("kmj,kj->km", step.lins[name].J[1:], step.q[1:] - step.q_bar[1:])
        errs[name] = float(np.sum(e[:, :2] ** 2) if name == "base" else np.sum(e ** 2))
    return errs.get("ee", np.nan), errs.get("base", np.nan), c


@pytest.mark.parametrize("first", ["ee", "base"])
def test_level_one_keeps_its_single_task_optimum(robot, first):
    params = HTMPCParams(sqp_iters_on_switch=8)
    single_ee, single_base, _ = converged_errors(robot, params, (first,))
    ee, base, _ = converged_errors(robot, params, (first, "base" if first == "ee" else "ee"))
    alone = single_ee if first == "ee" else single_base
    with_second = ee if first == "ee" else base
    N, tol = params.N, params.lex_tolerance
    # |e_1| ≤ |e_1*| + tol per node and component: the summed square may grow by at most this much
    m = 3 if first == "ee" else 2
    bound = alone + 2 * tol * np.sqrt(alone * N * m) + N * m * tol**2
    assert with_second <= bound + 1e-6


def test_level_two_improves_without_breaking_level_one(robot):
    params = HTMPCParams(sqp_iters_on_switch=8)
    ee_alone, _, _ = converged_errors(robot, params, ("ee",))
    ee, base, _ = converged_errors(robot, params, ("ee", "base"))
    c_free = lockstep(HTMPC(robot, params))
    refs = References(order=("ee",), ee=EE, switched=True)
    c_free.solve(ready_state(), refs, None)
    free_base = float(np.sum(c_free.last_step.q[1:, :2] ** 2))  # base error when nobody cares about it
    assert base < free_base  # level 2 pulled the base toward its goal …
    assert ee <= ee_alone + 0.05  # … within the (7c) tolerance of level 1


def _terminal_ee_error(robot, c) -> float:
    return float(np.linalg.norm(robot.ee_pose(c.last_step.q[-1])[:3, 3] - EE.position[0]))


def test_weighted_sum_breaks_level_one(robot):
    lex = HTMPCParams(sqp_iters_on_switch=8)
    weighted = HTMPCParams(sqp_iters_on_switch=8, hierarchy="weighted")
    ee_alone, _, _ = converged_errors(robot, lex, ("ee",))
    ee_lex, _, c_lex = converged_errors(robot, lex, ("ee", "base"))
    ee_sum, _, c_sum = converged_errors(robot, weighted, ("ee", "base"))
    assert ee_lex < ee_alone + 0.05
    assert ee_sum > 1.2 * ee_lex  # the base cost drags the EE away from its goal over the horizon …
    assert _terminal_ee_error(robot, c_sum) > 5 * _terminal_ee_error(robot, c_lex)  # … and at its end
