"""Fault handling: when a solve fails, times out or sees a non-finite state, the controller keeps the
previous plan, shifted to now, and decelerates along it to a stop within the acceleration limits
(`brake_along`); without a previous plan every joint brakes from its measured velocity, all stopping
together (`braking_plan`). No NaN and no over-limit velocity or acceleration leaves.

Braking along a plan is a time scaling: the plan is followed at path time s(t) with ṡ = 1 − t/T_b, so
the command is q̇ = v_prev(s) ṡ with acceleration a_prev(s) ṡ² − v_prev(s)/T_b; T_b is the shortest
braking time (from a geometric list) that keeps this within a_max on every joint.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from core.robot.limits import JointLimits
from core.types import Plan, PlanReason, PlanStatus, RobotState


def braking_plan(state: RobotState, limits: JointLimits, N: int, dt: float, status: PlanStatus, message: str,
                 ee_path: np.ndarray | None = None, n_levels: int = 0, reason: PlanReason = PlanReason.NONE) -> Plan:
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
                solve_ms=tuple([0.0] * n_levels), status=status, message=message, reason=reason)


def plan_is_safe(plan: Plan, limits: JointLimits, tol: float = 1e-6) -> bool:
    """Finite everywhere and within the velocity (the base's planar speed too) and acceleration limits."""
    arrays = (plan.q, plan.v, plan.u)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return False
    planar = np.hypot(plan.v[:, 0], plan.v[:, 1])
    return bool(np.all(np.abs(plan.v) <= limits.v_max + tol) and np.all(planar <= limits.planar_speed + tol)
                and np.all(np.abs(plan.u) <= limits.a_max + tol))


def _prev_at(plan: Plan, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, v, a of a plan at plan times tau (n,) ≥ 0: piecewise-constant a, as `Plan.velocity_at` reads it
    (held at the last node's velocity with a = 0 past the horizon)."""
    n = plan.u.shape[0]
    k = np.clip((tau // plan.dt).astype(int), 0, n)
    r = tau - k * plan.dt
    a = np.vstack([plan.u, np.zeros((1, plan.u.shape[1]))])[k]
    v = plan.v[k] + a * r[:, None]
    q = plan.q[k] + plan.v[k] * r[:, None] + 0.5 * a * r[:, None] ** 2
    return q, v, a


def _braking_time(plan: Plan, s0: float, limits: JointLimits, samples: int = 200) -> float | None:
    """Shortest T_b (from a geometric list up to what the plan's horizon covers) whose time scaling keeps
    every joint's acceleration within a_max; None if there is none."""
    horizon = plan.dt * plan.u.shape[0]
    _, v0, _ = _prev_at(plan, np.array([s0]))
    t_min = float(np.max(np.abs(v0[0]) / limits.a_max))
    if t_min < 1e-9:
        return 0.0
    for t_b in t_min * 1.25 ** np.arange(16):
        t = np.linspace(0.0, t_b, samples)
        s_dot = 1.0 - t / t_b
        s = s0 + t - t**2 / (2.0 * t_b)
        if s[-1] > horizon + plan.dt:
            return None
        _, v, a = _prev_at(plan, s)
        acc = a * s_dot[:, None] ** 2 - v / t_b
        if np.all(np.abs(acc) <= limits.a_max * (1.0 - 1e-6)):
            return float(t_b)
    return None


def brake_along(plan: Plan, t: float, limits: JointLimits, N: int, dt: float, status: PlanStatus,
                message: str, reason: PlanReason = PlanReason.NONE) -> Plan | None:
    """The previous `plan`, shifted to time t, slowed down to a stop along its own path within a_max.

    A plan that is already a braking plan (FALLBACK or STOPPING) is returned unchanged but for its status
    and message: it keeps decelerating. None when the plan cannot be followed (t outside it, no feasible
    T_b, or a stop that would not fit in N·dt).
    """
    if plan.status in (PlanStatus.FALLBACK, PlanStatus.STOPPING):
        return replace(plan, status=status, message=message, reason=reason)
    s0 = t - plan.t
    if not (np.isfinite(s0) and 0.0 <= s0 <= plan.dt * plan.u.shape[0]):
        return None
    t_b = _braking_time(plan, s0, limits)
    if t_b is None or t_b > N * dt:  # the stop must fall inside the plan handed out (zero command after it)
        return None
    tk = dt * np.arange(N + 1)
    if t_b > 0.0:
        s_dot = np.clip(1.0 - tk / t_b, 0.0, 1.0)
        s = s0 + np.minimum(tk, t_b) - np.minimum(tk, t_b) ** 2 / (2.0 * t_b)
    else:
        s_dot, s = np.zeros(N + 1), np.full(N + 1, s0)
    q, v, _ = _prev_at(plan, s)
    v = v * s_dot[:, None]
    u = np.diff(v, axis=0) / dt
    ee = plan.ee_path[np.clip(np.round(s / plan.dt).astype(int), 0, len(plan.ee_path) - 1)]
    return Plan(t=t, dt=dt, q=q, v=v, u=u, base_path=q[:, :3].copy(), ee_path=ee,
                task_errors=plan.task_errors, solve_ms=tuple(0.0 for _ in plan.solve_ms), status=status,
                message=message, reason=reason, extras={"braking_time_s": t_b})
