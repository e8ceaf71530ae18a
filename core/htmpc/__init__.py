"""Perceptive hierarchical-task MPC: cost terms, collision constraints (EDF / CBF), the lexicographic solve.

`HTMPC(robot, params).solve(state, refs, edf) -> Plan` is the controller; `edf` is anything with vectorised
`distance(p)` and `gradient(p)` (a `DistanceField`, e.g. a map's `LocalEDF`), or None for no collision rows.
"""

from core.htmpc.distance_field import DistanceField
from core.htmpc.htmpc import HTMPC, SolveCounts
from core.htmpc.safety import braking_plan, plan_is_safe
from core.params import HTMPCParams
from core.types import BaseReference, EEReference, Plan, PlanReason, PlanStatus, References, RobotState

__all__ = ["HTMPC", "BaseReference", "DistanceField", "EEReference", "HTMPCParams", "Plan", "PlanReason",
           "PlanStatus", "References", "RobotState", "SolveCounts", "braking_plan", "plan_is_safe"]
