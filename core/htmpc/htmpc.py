"""The perceptive hierarchical-task MPC (docs/method.md, eqs. 6–8 and 10).

Each control step solves, for the active subtask's task order [T_1 … T_L], a sequence of single-task
MPCs: level l minimises J_l + J_aux subject to the dynamics, bounds, the collision rows from the EDF
and |e_i| ≤ |e_i*| + tol for each earlier level i (7c), with a tolerance only where the plan is re-planned
(not at node 1, which the robot executes) and the step checked on the exact errors (`_keep_priority`):
so the order holds in closed loop, not only in one solve. The nonlinear problem is handled by
Gauss-Newton SQP in real-time-iteration form: one structured QP (HPIPM) per level per step, around the
previous solution shifted to now; right after a task switch, several iterations (until the plan stops
moving, `sqp_step_tol`), each damped (`sqp_damping`) and bounded by an adaptive trust region.

Public API: `HTMPC(robot, params).solve(state, refs, edf) -> Plan` (edf: anything with vectorised
`distance(p)` and `gradient(p)`, e.g. `core.types.LocalEDF`, or None for no collision rows), `reset()`,
`set_delta_safe(m)` and `enforce_timeout` (False in lockstep runs: simulated time waits for the solver). A failed QP, an
exception of any type, a non-finite state or map, a slow solve or an out-of-limit solution gives a braking
plan along the last plan handed out (status FALLBACK or STOPPING, why in `reason` (a `PlanReason`), the words
in `message`; safety.py);
`counts` tallies them (`SolveCounts`). One solve at a time per instance: the kinematics and the QPs evaluate in
place on the controller's preallocated buffers (callers serialise steps, e.g. `app.runtime.closed_loop`'s step lock).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from core.htmpc.box_barrier import BoxBarrier
from core.htmpc.collision_constraint import (
    CollisionConstraint,
    CollisionRows,
    DistanceField,
    StepRows,
    step_rows,
)
from core.htmpc.horizon_kinematics import HorizonKinematics, HorizonKinematicsEvaluator
from core.htmpc.level_problem import (
    LexBound,
    add_lex_rows,
    base_arrays,
    lex_limits,
    lex_tolerances,
    linearised_errors,
    set_speed_rows,
    task_cost,
    variable_bounds,
)
from core.htmpc.ocp_qp import NQ, QPLayout, StructuredQP
from core.htmpc.safety import brake_along, braking_plan, plan_is_safe
from core.htmpc.task_costs import (
    BaseTaskCost,
    EEBaseFrameTaskCost,
    EETaskCost,
    Linearisation,
    PostureTaskCost,
    TaskCost,
)
from core.params import HTMPCParams
from core.robot.model import RobotModel
from core.types import Plan, PlanReason, PlanStatus, References, RobotState

log = logging.getLogger(__name__)

PREBUILT_LEX_ROWS = (0, 2, 3, 6)
"""(7c) rows a level can carry: none (level 1), base xy or xy+yaw, EE position or pose (level 2)."""

TRUST_COST_FLOOR = 1e-4
"""Cost changes below this (relative to 1 + the cost) count as predicted well whatever their ratio."""

MIN_TRUST_SCALE = 0.125
"""The yaw/arm trust region never shrinks below 1/8 of `trust_region_rad`, and it recovers by ×2 at
every new control step, so a bad step cannot freeze the plan."""


@dataclass
class _Iterate:
    t: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray


@dataclass
class SolveCounts:
    """What went wrong how often since the controller was made (experiments report these)."""

    solves: int = 0
    level1_qp_failures: int = 0
    """Failed level-1 QPs: the step brakes (safety.py)."""
    lower_level_qp_failures: int = 0
    """Failed QPs of levels ≥ 2: the step hands out the level above's plan."""
    qp_rescues: int = 0
    """QPs that stalled and were solved again in HPIPM's rescue mode (`ocp_qp.RESCUE_MODE`)."""
    exceptions: int = 0
    timeouts: int = 0
    other_fallbacks: int = 0
    """Non-finite states, solutions outside the limits."""

    @property
    def qp_failures(self) -> int:
        """QPs that failed even in the rescue mode, at any level."""
        return self.level1_qp_failures + self.lower_level_qp_failures


@dataclass
class StepResult:
    """What one SQP iteration produced (kept for diagnostics, tests and the IPOPT comparison)."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    slack: np.ndarray
    level_ms: list[float]
    level_errors: list[np.ndarray]
    failed_level: int | None
    message: str
    kin: HorizonKinematics | None = None
    lins: dict[str, Linearisation] | None = None
    q_bar: np.ndarray | None = None
    min_h: float = float("nan")
    """Smallest barrier value h = EDF − r − delta_safe at node 1 (m); NaN without a map."""
    kin_new: HorizonKinematics | None = None
    """FK at the new iterate (set by the trust-region test)."""
    level_solutions: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    """(q, v, a) of each level's QP solution, in order (the last is the plan)."""
    qp_iterations: int = 0
    """HPIPM iterations summed over the levels (rescue attempts included)."""
    hpipm_ms: float = 0.0
    """HPIPM's own time (casadi's `t_wall_solver`) summed over the levels: the rest of a step is Python."""


class HTMPC:
    """Lexicographic whole-body MPC for the 9-joint mobile manipulator."""

    def __init__(self, robot: RobotModel, params: HTMPCParams | None = None) -> None:
        self.robot = robot
        self.params = params or HTMPCParams()
        p = self.params
        self.tasks = {"base": BaseTaskCost(p.Q_base), "ee": EETaskCost(p.Q_ee), "posture": PostureTaskCost(p.Q_posture)}
        self.ee_base_task = EEBaseFrameTaskCost(p.Q_ee)
        """The EE task when the reference is in the base frame (`EEReference.frame == 'base'`)."""
        self.kinematics = HorizonKinematicsEvaluator(robot, p.N + 1)
        self._step_kinematics = HorizonKinematicsEvaluator(robot, 2)
        """FK at the next control instant (`StepRows`), as a two-node horizon whose node 1 is that instant."""
        boxes = BoxBarrier(robot.boxes, p.box_iterations)
        self.collision = CollisionConstraint(robot.sphere_radii, p.delta_safe_m, p.gamma, p.constraint, boxes)
        self.row_names = collision_row_names(robot, boxes)
        self._qps: dict[int, StructuredQP] = {}
        self.slack_group = slack_groups(self.row_names, p.slack_groups)
        for n_lex in PREBUILT_LEX_ROWS:  # tens of ms each: not inside the first control step (docs/decisions.md)
            self._qp(n_lex)
        self.trust = np.array([p.trust_region_m] * 2 + [p.trust_region_rad] * 7)
        self.trust_scale = 1.0
        """Adapted by the ratio of actual to predicted task-cost decrease (a trust-region SQP)."""
        self._previous: _Iterate | None = None
        self._carry = 0
        """SQP iterations of the latest task switch still to spend on the following steps (`_iterations`)."""
        self.last_step: StepResult | None = None
        self._last_plan: Plan | None = None
        """The plan handed out last: a fault brakes along it (safety.brake_along)."""
        self.counts = SolveCounts()
        self.enforce_timeout = True
        """Live runs discard slow solves (`solve_timeout_ms`); lockstep runs turn this off to stay
        deterministic (simulated time does not advance while the solver works)."""

    @property
    def delta_safe_m(self) -> float:
        """The safety margin delta_safe the collision rows keep now (m)."""
        return self.collision.delta_safe_m

    def set_delta_safe(self, delta_safe_m: float) -> None:
        """Keep `delta_safe_m` from the next step on (the closed loop grows it by the pose's uncertainty:
        `core/localization/health.py`); `HTMPCParams.delta_safe_m` stays what was configured."""
        if not (np.isfinite(delta_safe_m) and delta_safe_m >= 0.0):
            raise ValueError(f"delta_safe must be a finite distance >= 0 m, got {delta_safe_m}")
        self.collision.delta_safe_m = float(delta_safe_m)

    def reset(self) -> None:
        """Forget the warm start (e.g. after a reset of the world)."""
        self._previous = None
        self._carry = 0
        self.last_step = None
        self.trust_scale = 1.0
        self._last_plan = None

    # --- building blocks ---------------------------------------------------------------------------

    def _qp(self, n_lex: int) -> StructuredQP:
        if n_lex not in self._qps:
            layout = QPLayout(self.params.N, self.collision.n_rows, n_lex, self.slack_group)
            self._qps[n_lex] = StructuredQP(layout, self.params.dt_s)
        return self._qps[n_lex]

    def warm_start(self, state: RobotState) -> _Iterate:
        """The previous solution shifted to now and rolled out from the measured state (zero input if none)."""
        N, dt = self.params.N, self.params.dt_s
        lim = self.robot.limits
        a = np.zeros((N, 9))
        prev = self._previous
        if prev is not None:
            j = ((state.t - prev.t) / dt + np.arange(N) + 0.5).astype(int)
            kept = j < N
            a[kept] = prev.a[np.clip(j[kept], 0, N - 1)]
        v0 = lim.clip_velocity(state.v)
        # v_{k+1} = clip(v_k + dt a_k), q_{k+1} = q_k + dt (v_k + v_{k+1}) / 2: cumulative sums (the same additions
        # in the same order as the loop) unless a velocity limit clips, then node by node
        v = np.add.accumulate(np.vstack([v0, dt * a]))
        if np.any(np.abs(v) > lim.v_max):
            v[0] = v0
            for k in range(N):
                v[k + 1] = np.clip(v[k] + dt * a[k], -lim.v_max, lim.v_max)
        q = np.add.accumulate(np.vstack([state.q, dt * 0.5 * (v[:-1] + v[1:])]))
        return _Iterate(state.t, q, v, a)

    def _linearise(self, order: list[str], refs: References, q_bar: np.ndarray,
                   kin: HorizonKinematics) -> dict[str, Linearisation]:
        out = {}
        for name in order:
            task = self._task(name, refs)
            out[name] = task.linearise(q_bar, kin, task.reference(refs))
        return out

    def _task(self, name: str, refs: References) -> TaskCost:
        """The task object for `name` under these references (the base-frame EE task for a base-frame target)."""
        base_frame = name == "ee" and refs.ee is not None and refs.ee.frame == "base"
        return self.ee_base_task if base_frame else self.tasks[name]

    # --- one SQP iteration -------------------------------------------------------------------------

    def iterate(self, x0: np.ndarray, it: _Iterate, order: list[str], refs: References,
                edf: DistanceField | None, damping: float | None = None) -> StepResult:
        """Linearise at the iterate and solve the levels; returns the last successful level's solution.
        `damping`: λ of the Levenberg-Marquardt term (default `params.sqp_damping`)."""
        p = self.params
        kin = self.kinematics(it.q, it.v)
        lins = self._linearise(order, refs, it.q, kin)
        rows, step = self._collision_rows(x0, it, kin, edf) if edf is not None else (None, None)
        lim = self.robot.limits
        levels = [order] if p.hierarchy == "weighted" else [[name] for name in order]
        bounds: list[LexBound] = []
        tol = lex_tolerances(p)
        best, level_ms, level_errors, solutions = None, [], [], []
        failed, message, qp_iterations, hpipm_ms = None, "", 0, 0.0
        guess = None
        for i, level in enumerate(levels):
            n_lex = sum(b.lin.e0.shape[1] for b in bounds)
            qp = self._qp(n_lex)
            arrays = base_arrays(qp, p, it.q, rows, damping, step)
            for name in level:
                task_cost(arrays, qp, lins[name], it.q, p)
            add_lex_rows(arrays, qp, bounds, it.q, tol)
            set_speed_rows(arrays, qp, x0, lim.planar_speed)
            lbx, ubx = variable_bounds(qp.layout, x0, lim.q_min, lim.q_max, lim.v_max, lim.a_max, p.dt_s,
                                       it.q, self._trust_now())
            if guess is None:  # level 1 starts from the linearisation point, level l from level l−1's optimum
                guess = qp.layout.pack(it.q, it.v, it.a)
            sol = qp.solve(arrays.h, arrays.g, arrays.a, arrays.lba, arrays.uba, lbx, ubx, guess)
            level_ms.append(sol.solve_ms)
            qp_iterations += sol.iterations
            hpipm_ms += sol.hpipm_ms if np.isfinite(sol.hpipm_ms) else 0.0
            self.counts.qp_rescues += sol.rescued
            if not sol.success:
                self.counts.level1_qp_failures += i == 0
                self.counts.lower_level_qp_failures += i > 0
                failed, message = i, f"level {i + 1} QP failed ({sol.status})"
                log.warning(message)
                break
            z = sol.z if not bounds else self._keep_priority(qp.layout, guess, sol.z, order[:len(bounds)], refs,
                                                             tol)
            q, v, a = qp.layout.states(z)
            best = (q, v, a, qp.layout.slacks(z))
            solutions.append((q, v, a))
            guess = z
            for name in level:
                e = linearised_errors(lins[name], q, it.q)
                level_errors.append(e)
                bounds.append(LexBound(lins[name], e))
        if best is None:
            return StepResult(it.q, it.v, it.a, np.zeros(0), level_ms, level_errors, 0, message, kin, lins, it.q,
                              qp_iterations=qp_iterations, hpipm_ms=hpipm_ms)
        q, v, a, s = best
        min_h = float(rows.h[0].min()) if rows is not None else float("nan")
        return StepResult(q, v, a, s, level_ms, level_errors, failed, message, kin, lins, it.q, min_h,
                          level_solutions=solutions, qp_iterations=qp_iterations, hpipm_ms=hpipm_ms)

    def _collision_rows(self, x0: np.ndarray, it: _Iterate, kin: HorizonKinematics,
                        edf: DistanceField) -> tuple[CollisionRows, StepRows]:
        """The collision rows at nodes 1..N−1 and at the next control instant τ (`StepRows`, linearised on the
        iterate's first interval), from one batch of EDF queries."""
        N, tau = self.params.N, 1.0 / self.params.control_rate_hz
        q_tau = it.q[0] + tau * it.v[0] + 0.5 * tau**2 * it.a[0]
        v_tau = it.v[0] + tau * it.a[0]
        q2, v2 = np.stack([q_tau, q_tau]), np.stack([v_tau, v_tau])
        at_tau = self._step_kinematics(q2, v2)
        rows = self.collision.rows_at(
            np.vstack([it.q[1:N], q_tau]), np.vstack([it.v[1:N], v_tau]), np.concatenate([kin.P[1:N], at_tau.P[1:]]),
            np.concatenate([kin.JP[1:N], at_tau.JP[1:]]), np.concatenate([kin.dvel()[1:N], at_tau.dvel()[1:]]), edf)
        nodes = CollisionRows(rows.a_q[:-1], rows.a_v[:-1], rows.lb[:-1], rows.h[:-1])
        last = CollisionRows(rows.a_q[-1:], rows.a_v[-1:], rows.lb[-1:], rows.h[-1:])
        return nodes, step_rows(last, x0[:NQ], x0[NQ:], tau)

    def _true_errors(self, q: np.ndarray, names: list[str], refs: References) -> np.ndarray:
        """The exact (nonlinear) errors of tasks `names` at nodes 1..N of q, side by side (N, Σm)."""
        tasks = [self._task(n, refs) for n in names]
        kin = self.kinematics(q) if any(t.needs_kinematics for t in tasks) else None
        return np.concatenate([t.compute_error(q, kin, t.reference(refs)) for t in tasks], axis=1)[1:]

    def _keep_priority(self, layout: QPLayout, z_prev: np.ndarray, z_new: np.ndarray, earlier: list[str],
                       refs: References, tol: np.ndarray) -> np.ndarray:
        """(7c) with the exact errors: the longest step from the previous level's solution toward this
        level's (z_prev + α (z_new − z_prev), α halved from 1 to 1/8, else 0) that keeps every earlier task's
        exact error within `lex_limits` of its exact error at the previous level's solution.

        The QP bounds the Gauss-Newton model of the earlier errors; a lower level exploits the model's error
        (at a stretched arm, 0.5 rad of arm motion that the model says keeps the EE in place moved it 0.7 m),
        and in closed loop level 1 then settles far from its optimum. Every α is feasible for this level's QP:
        both ends are, and its constraints are linear."""
        if all(self._task(n, refs).linear_in_q for n in earlier):
            return z_new  # errors affine in q (the base's): the QP's bound is exact
        e_ref = self._true_errors(layout.states(z_prev)[0], earlier, refs)
        lo, hi = lex_limits(e_ref, tol)
        step = z_new - z_prev
        for alpha in (1.0, 0.5, 0.25, 0.125):
            z = z_prev + alpha * step
            e = self._true_errors(layout.states(z)[0], earlier, refs)
            if np.all(e >= lo - 1e-9) and np.all(e <= hi + 1e-9):
                return z
        return z_prev

    # --- the control step --------------------------------------------------------------------------

    def solve(self, state: RobotState, refs: References, edf: DistanceField | None) -> Plan:
        """One control step: a plan from the measured state, or a braking plan if anything is wrong."""
        p = self.params
        t0 = time.perf_counter()
        self.counts.solves += 1
        order = [name for name in refs.order if self.tasks[name].reference(refs) is not None]
        n = len(order)
        if not (np.all(np.isfinite(state.q)) and np.all(np.isfinite(state.v)) and np.isfinite(state.t)):
            self.counts.other_fallbacks += 1
            return self._fallback(state, n, PlanReason.NON_FINITE_STATE, "non-finite robot state",
                                  PlanStatus.STOPPING)
        if not order:
            self._previous = None
            return braking_plan(state, self.robot.limits, p.N, p.dt_s, PlanStatus.STOPPING, "no task: holding",
                                n_levels=0, reason=PlanReason.NO_TASK)
        x0 = np.concatenate([state.q, self.robot.limits.clip_velocity(state.v)])
        self.trust_scale = min(1.0, 2.0 * self.trust_scale)
        it = self.warm_start(state)
        iters, carried = self._iterations(refs)
        damping = p.sqp_damping_on_switch if iters > 1 or carried else p.sqp_damping
        step, level_ms = None, np.zeros(len(order) if p.hierarchy == "lexicographic" else 1)
        sqp_iterations = qp_iterations = 0
        hpipm_ms = 0.0
        try:
            for _ in range(max(1, iters)):
                step = self.iterate(x0, it, order, refs, edf, damping)
                level_ms[: len(step.level_ms)] += step.level_ms
                sqp_iterations += 1
                qp_iterations += step.qp_iterations
                hpipm_ms += step.hpipm_ms
                if step.failed_level == 0:
                    break
                self._adapt_trust(step, order, refs)
                converged = float(np.max(np.abs(step.q - it.q))) < p.sqp_step_tol
                it = _Iterate(state.t, step.q, step.v, step.a)
                if converged:
                    self._carry = 0
                    break
        except Exception as err:  # any fault inside the solve brakes the robot; a dead control loop does not
            log.exception("HTMPC step raised")
            self.counts.exceptions += 1
            return self._fallback(state, n, PlanReason.CONTROLLER_ERROR,
                                  f"controller error: {type(err).__name__}: {err}")
        elapsed = (time.perf_counter() - t0) * 1e3
        if step is None or step.failed_level == 0:
            if step is None:
                return self._fallback(state, n, PlanReason.NO_ITERATION, "no iteration")
            return self._fallback(state, n, PlanReason.QP_FAILED, step.message)
        if self.enforce_timeout and elapsed > p.solve_timeout_ms:
            self.counts.timeouts += 1
            digits = 0 if round(elapsed) > round(p.solve_timeout_ms) else 1  # never "250 ms > 250 ms"
            return self._fallback(state, n, PlanReason.SOLVE_TIMEOUT,
                                  f"solve took {elapsed:.{digits}f} ms > {p.solve_timeout_ms:.0f} ms")
        plan = self._plan(state, order, refs, step, tuple(level_ms),
                          {"sqp_iterations": float(sqp_iterations), "qp_iterations": float(qp_iterations),
                           "hpipm_ms": hpipm_ms})
        if not plan_is_safe(plan, self.robot.limits, tol=1e-4):
            self.counts.other_fallbacks += 1
            return self._fallback(state, n, PlanReason.OUTSIDE_LIMITS, "solution outside the limits")
        self._previous = _Iterate(state.t, step.q, step.v, step.a)
        self.last_step = step
        self._last_plan = plan
        return plan

    def _iterations(self, refs: References) -> tuple[int, bool]:
        """SQP iterations for this step, and whether they are carried over from a task switch. A switch (or no warm
        start) gets `sqp_iters_on_switch` now and `sqp_switch_carry` more, spread over the following steps at
        most `sqp_iters_on_switch` a step, until spent or the plan stops moving (`sqp_step_tol`): the task's first
        steps stay within a control period while the plan converges as far as before."""
        p = self.params
        if refs.switched or self._previous is None:
            self._carry = p.sqp_switch_carry
            return p.sqp_iters_on_switch, False
        if self._carry <= 0:
            return p.sqp_iters, False
        iters = min(self._carry, p.sqp_iters_on_switch)
        self._carry -= iters
        return max(iters, p.sqp_iters), True

    def _true_cost(self, q: np.ndarray, kin: HorizonKinematics, order: list[str], refs: References) -> float:
        """Σ over tasks and nodes 1..N of ½‖e‖²_W with the exact (nonlinear) errors."""
        total = 0.0
        for name in order:
            task = self._task(name, refs)
            e = task.compute_error(q, kin, task.reference(refs))
            total += 0.5 * float(np.sum(task.weights[: e.shape[1]] * e[1:] ** 2))
        return total

    def _trust_now(self) -> np.ndarray:
        """The trust region: base x, y fixed (they enter the FK linearly); yaw and arm scaled by the test."""
        trust = self.trust.copy()
        trust[2:] *= self.trust_scale
        return trust

    def _adapt_trust(self, step: StepResult, order: list[str], refs: References) -> None:
        """Shrink the trust region when the Gauss-Newton model mispredicted a task's cost change, widen it
        when it predicted every task well. Each task is checked on its own: in a lexicographic step a
        lower level's cost may rise as planned, and a period-2 oscillation at the stretched arm predicts
        nearly no change of the summed cost while each level's cost jumps. Also evaluates the FK of the
        new iterate once, which the plan reuses for its EE path."""
        kin_new = self.kinematics(step.q)
        step.kin_new = kin_new
        lins, q_bar = step.lins, step.q_bar
        assert lins is not None and q_bar is not None, "a step that produced a plan has its linearisation"
        worst = 0.0
        for name in order:
            lin = lins[name]
            old = 0.5 * float(np.sum(lin.weights * lin.e0[1:] ** 2))
            new = self._true_cost(step.q, kin_new, [name], refs)
            e = lin.e0[1:] + np.einsum("kmj,kj->km", lin.J[1:], step.q[1:] - q_bar[1:])
            predicted = 0.5 * float(np.sum(lin.weights * e**2))
            scale = abs(old - predicted) + TRUST_COST_FLOOR * (1.0 + old)
            worst = max(worst, abs(new - predicted) / scale)
        if worst > 0.75:
            self.trust_scale = max(self.trust_scale * 0.5, MIN_TRUST_SCALE)
        elif worst < 0.25:
            self.trust_scale = min(self.trust_scale * 2.0, 1.0)

    def _fallback(self, state: RobotState, n_levels: int, reason: PlanReason, message: str,
                  status: PlanStatus = PlanStatus.FALLBACK) -> Plan:
        """Keep the previous plan, shifted to now, and stop along it within the limits (safety.py); without
        one (or if it cannot be followed), brake every joint from the measured velocity."""
        log.warning("HTMPC fallback: %s", message)
        p, lim = self.params, self.robot.limits
        self._previous = None
        plan = None
        if self._last_plan is not None and np.isfinite(state.t):
            plan = brake_along(self._last_plan, state.t, lim, p.N, p.dt_s, status,
                               f"{message}; braking along the previous plan", reason)
        if plan is None:
            plan = braking_plan(state, lim, p.N, p.dt_s, status, f"{message}; braking", n_levels=n_levels,
                                reason=reason)
        self._last_plan = plan
        return plan

    def _plan(self, state: RobotState, order: list[str], refs: References, step: StepResult,
              level_ms: tuple[float, ...], extras: dict[str, float]) -> Plan:
        """The plan of a step (its EE path from the FK the trust-region test already evaluated); `extras` adds to
        the plan's diagnostics (SQP and QP iterations of the step, HPIPM's own time)."""
        p = self.params
        kin, lins, q_bar = step.kin, step.lins, step.q_bar
        assert kin is not None and lins is not None and q_bar is not None, "a step that produced a plan is whole"
        errors = tuple(float(np.linalg.norm(lins[name].e0[0])) for name in order)
        if step.kin_new is not None:
            ee_path = step.kin_new.p.copy()
        else:  # Gauss-Newton prediction p̄ + J_p (q − q̄)
            ee_path = kin.p + np.einsum("kij,kj->ki", kin.Jp, step.q - q_bar)
        v = self.robot.limits.clip_velocity(step.v)
        a = np.clip(step.a, -self.robot.limits.a_max, self.robot.limits.a_max)
        max_slack = float(step.slack.max()) if step.slack.size else 0.0
        status = PlanStatus.SLACK if max_slack > 1e-3 else PlanStatus.OK
        message = step.message or (f"collision slack {max_slack:.3f}" if status == PlanStatus.SLACK else "")
        return Plan(t=state.t, dt=p.dt_s, q=step.q, v=v, u=a, base_path=step.q[:, :3].copy(), ee_path=ee_path,
                    task_errors=errors, solve_ms=level_ms, status=status, message=message,
                    reason=PlanReason.NONE if step.failed_level is None else PlanReason.QP_FAILED, min_h=step.min_h,
                    extras={"max_slack": max_slack, "levels": float(len(step.level_ms)), **extras})


def collision_row_names(robot: RobotModel, boxes: BoxBarrier) -> list[str]:
    """Names of a node's collision rows, in order: the spheres, then the base boxes' sides."""
    return [s.name for s in robot.spheres] + boxes.names


BASE_ROWS = ("mount", "base_body", "base_rack")
"""Rows of the parts fixed to the base (prefixes of `collision_row_names`)."""


def slack_groups(names: list[str], kind: str) -> np.ndarray:
    """Slack index per collision row: 'sphere' (one each), 'body' (base vs arm) or 'node' (one per node)."""
    if kind == "sphere":
        return np.arange(len(names))
    if kind == "body":
        return np.array([0 if n.startswith(BASE_ROWS) else 1 for n in names])
    if kind == "node":
        return np.zeros(len(names), int)
    raise ValueError(f"slack_groups must be 'sphere', 'body' or 'node', got {kind!r}")

