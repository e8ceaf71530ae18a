"""Fault handling: when a solve fails, times out or sees a non-finite state, the controller returns a
braking plan instead: every joint decelerates within its limit and all stop together (so the robot
keeps its current direction of motion while it stops). No NaN and no over-limit velocity leaves."""

from __future__ import annotations

import numpy as np

from core.robot.limits import JointLimits
from core.types import Plan, PlanStatus, RobotState


def braking_plan(state: RobotState, limits: JointLimits, N: int, dt: float, status: PlanStatus, message: str,
                 ee_path: np.ndarray | None = None, n_levels: int = 0) -> Plan:
    """A plan that brings every joint from state.v to rest at most at a_max, all stopping at the same time."""
    q0 = np.where(np.isfinite(state.q), state.q, 0.0)
    v0 = limits.clip_velocity(np.asarray(state.v, float))
    if not np.all(np.isfinite(state.q)) or not np.all(np.isfinite(state.v)):
        v0 = np.zeros_like(v0)  # cannot brake from an unknown velocity: command rest
    t_stop = float(np.max(np.abs(v0) / limits.a_max)) if np.any(v0) else 0.0
    t = dt * np.arange(N + 1)
    scale = np.clip(1.0 - t / t_stop, 0.0, 1.0) if t_stop > 0 else np.zeros(N + 1)
    v = scale[:, None] * v0
    u = np.diff(v, axis=0) / dt
    # position: integral of the linear ramp, exact per interval
    q = q0 + np.concatenate([[np.zeros(9)], np.cumsum(0.5 * (v[:-1] + v[1:]) * dt, axis=0)])
    ee = ee_path if ee_path is not None else np.zeros((N + 1, 3))
    return Plan(t=state.t if np.isfinite(state.t) else 0.0, dt=dt, q=q, v=v, u=u,
                base_path=q[:, :3].copy(), ee_path=ee, task_errors=tuple([np.nan] * n_levels),
                solve_ms=tuple([0.0] * n_levels), status=status, message=message)


def plan_is_safe(plan: Plan, limits: JointLimits, tol: float = 1e-6) -> bool:
    """Finite everywhere and within the velocity and acceleration limits."""
    arrays = (plan.q, plan.v, plan.u)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return False
    return bool(np.all(np.abs(plan.v) <= limits.v_max + tol) and np.all(np.abs(plan.u) <= limits.a_max + tol))
