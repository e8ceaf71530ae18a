"""HTMPC solve time over a closed-loop navigation run (CBF on, all collision rows, ground-truth EDF):
1 and 2 levels at N = 10, 2 levels at N = 20, and in a second two-level run the IPOPT reference on the same
states (speed ratio and cost gap; our steps there are slower, `l2_n10_beside_ipopt_median_ms`: IPOPT's work
between them evicts the caches, so the solve times come from runs without it). Beside them the controller's
two promises: strict priority in closed loop (`priority_leak_m`, `bench/priority_leak.py`) and collision
geometry that covers the robot (`sphere_cover_gap_m`: the largest distance of any sampled MuJoCo robot
surface point outside the controller's spheres and base boxes, `core/sim/collision_cover.py`).

    python -m bench.htmpc_solve [--quick] [--switches-only]

A task's first step (`first_step_ms_max` over >= 10 task switches, bench/task_switch.py): right after a switch the
controller iterates its SQP (`sqp_iters_on_switch`, by default all five in that step); the same sequence with
them spread over the first steps (2 + 2 + 1, `sqp_switch_carry`) is measured beside it (`*_spread`).

Timings are wall-clock per `HTMPC.solve` call (everything: warm start, FK, linearisation, the QPs, the
plan), including the first step after the task starts (several SQP iterations). The thread's CPU time
is reported beside them: the other engineers' jobs share the 2 cores, and the gap between the two shows
how much of a figure is waiting.

The cost gap compares the plan we hand out (our last level's QP solution after one real-time iteration)
with IPOPT's converged last level, both evaluated with the same nonlinear objective J_L + J_aux (exact
FK and SO(3) log). Level 1 is compared on its task cost J_1 alone, our level-1 QP solution against
IPOPT's level-1 optimum: that is what (7c) hands on. (J_aux of our level-1 solution is not comparable:
the Levenberg-Marquardt damping keeps the joints level 1 does not use where level 2 last put them.)
How far our plans violate IPOPT's exact-kinematics collision rows (the price of linearising them) is
reported beside it, in the rows' units (m/s for the CBF at gamma = 1). IPOPT keeps the EDF linearised
at the warm start's sphere centres (a casadi interpolant of the grid is impractical), so the comparison
runs on real-time-iteration steps only, where our one QP per level linearises there too; the first
step after the task starts iterates and re-linearises the EDF, and is timed but not compared.

The tail: every two-level solve slower than `TAIL_FACTOR` × the median is put down to one cause, the first
that applies: several SQP iterations (the task's first step), a QP rescue, a garbage collection during the
solve, waiting (the thread's CPU time stayed under the tail threshold: another process had the core), many QP
iterations (over 1.5 × the median), else 'other'. The counts are printed and written as `tail_*` figures.
"""

from __future__ import annotations

import argparse
import gc
import os
import time
from dataclasses import dataclass, field, replace

import numpy as np
from rich.progress import track

import core.sim  # noqa: F401  (GL backend first)
from bench.priority_leak import priority_figures
from bench.report import bench_args, percentile, write_result
from bench.task_switch import run_switches
from core.htmpc import HTMPC
from core.htmpc.ipopt_reference import IpoptReference
from core.params import HTMPCParams, SensorParams
from core.robot.model import READY_Q, RobotModel
from core.scene import random_scene
from core.sim.collision_cover import cover_gaps
from core.sim.ground_truth import ground_truth_edf
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import PlanStatus, References
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.sequencer import Sequencer

IPOPT_TOL = 1e-6
"""IPOPT's tolerance for the speed ratio: the same order as HPIPM's 1e-6 residuals (ocp_qp.py)."""
TAIL_FACTOR = 2.0
"""A solve slower than this multiple of the median is in the tail (the target is p99 ≤ 2.5 × median)."""
TAIL_CAUSES = ("sqp_iterations", "qp_rescue", "garbage_collection", "waiting", "qp_iterations", "other")


class GCTimer:
    """Time spent in the garbage collector, read before and after a solve (`gc.callbacks`)."""

    def __init__(self) -> None:
        self.total_ms = 0.0
        self._start = 0.0
        gc.callbacks.append(self._callback)

    def _callback(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._start = time.perf_counter()
        else:
            self.total_ms += (time.perf_counter() - self._start) * 1e3

    def close(self) -> None:
        gc.callbacks.remove(self._callback)


@dataclass
class RunLog:
    """What one closed-loop run measured."""

    wall_ms: list[float] = field(default_factory=list)
    cpu_ms: list[float] = field(default_factory=list)
    ipopt_ms: list[float] = field(default_factory=list)
    ipopt_solver_ms: list[float] = field(default_factory=list)
    ours_at_ipopt_ms: list[float] = field(default_factory=list)
    gap_pct: list[list[float]] = field(default_factory=list)
    violation: list[float] = field(default_factory=list)
    fallbacks: int = 0
    qp_failures: int = 0
    qp_rescues: int = 0
    over_budget: int = 0
    """Solves slower than `solve_timeout_ms` (a live run would have braked)."""
    sqp_iterations: list[float] = field(default_factory=list)
    qp_iterations: list[float] = field(default_factory=list)
    rescued: list[bool] = field(default_factory=list)
    gc_ms: list[float] = field(default_factory=list)
    qp_ms: list[float] = field(default_factory=list)
    """Per solve: the level QPs' time, each HPIPM call with its Python around it (`Plan.solve_ms` summed)."""
    hpipm_ms: list[float] = field(default_factory=list)
    """Per solve: HPIPM's own time (casadi's `t_wall_solver`), summed over the levels."""

    def steady(self, values: list[float]) -> list[float]:
        """`values` of the solves that made one SQP iteration (not a task's first step)."""
        return [x for x, n in zip(values, self.sqp_iterations, strict=True) if n <= 1]

    def tail_causes(self) -> dict[str, int]:
        """How many solves over `TAIL_FACTOR` × the median each cause explains (the first that applies)."""
        wall = np.asarray(self.wall_ms)
        if wall.size == 0:
            return dict.fromkeys(TAIL_CAUSES, 0)
        threshold = TAIL_FACTOR * float(np.median(wall))
        many = 1.5 * float(np.median(self.qp_iterations))
        counts = dict.fromkeys(TAIL_CAUSES, 0)
        for i in np.nonzero(wall > threshold)[0]:
            causes = (self.sqp_iterations[i] > 1, self.rescued[i], self.gc_ms[i] > 0.2 * (wall[i] - threshold),
                      self.cpu_ms[i] <= threshold, self.qp_iterations[i] > many, True)
            counts[TAIL_CAUSES[causes.index(True)]] += 1
        return counts


def compare_with_ipopt(log: RunLog, reference: IpoptReference, controller: HTMPC, state, refs: References, edf,
                       warm, ms: float) -> None:
    """IPOPT on the same state, warm-started like the controller; the per-level cost gaps of our step."""
    step = controller.last_step
    res = reference.solve(state, refs, edf, warm.q, warm.v, warm.a, compare=step.level_solutions)
    if not res.success:
        return
    log.ipopt_ms.append(sum(res.level_ms))
    log.ipopt_solver_ms.append(sum(res.level_ms) - sum(res.eval_ms))
    log.ours_at_ipopt_ms.append(ms)
    last = 100.0 * (res.compared_objectives[-1] - res.level_objectives[-1]) / max(abs(res.level_objectives[-1]), 1e-9)
    first = 100.0 * (res.compared_task_costs[0] - res.level_task_costs[0]) / max(abs(res.level_task_costs[0]), 1e-9)
    log.gap_pct.append([first, last])
    log.violation.append(max(res.compared_violations))


def closed_loop(robot: RobotModel, params: HTMPCParams, levels: int, seconds: float, reference: IpoptReference | None,
                every: int, label: str) -> RunLog:
    """Drive the paper's random scene; time every solve; compare with IPOPT every `every` control steps."""
    scene = random_scene(0)
    world = SimWorld(robot, scene=scene)
    q0 = READY_Q.copy()
    q0[:3] = scene.robot_start
    world.set_robot(q0)
    sim = SimRobot(world, cameras=(), sensor=SensorParams.ideal())
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=scene.goal[0], y=scene.goal[1], yaw_deg=0.0),
                                             timeout_s=1e3)])
    sequencer = Sequencer(robot, seq, n_nodes=params.N, dt=params.dt_s)
    controller = HTMPC(robot, params)
    controller.enforce_timeout = False  # lockstep: a slow solve (a busy machine) must not change the run
    occupied = np.concatenate([np.random.default_rng(0).uniform(-0.5, 0.5, (300, 3)) * b.size + b.position
                               for b in scene.boxes])
    log = RunLog()
    gc_timer = GCTimer()
    plan = None
    for k in track(range(int(seconds / 0.01)), description=label, transient=True):
        state = sim.observe().state
        if k % 10 == 0:
            refs = sequencer.update(state, occupied, state.t)
            if refs is None:
                break
            if levels == 1:
                refs = References(order=refs.order[:1], base=refs.base, ee=None, switched=refs.switched)
            edf = ground_truth_edf(world.obstacles(), state.q[:2])
            warm = controller.warm_start(state)
            rescues, gc0 = controller.counts.qp_rescues, gc_timer.total_ms
            t0, c0 = time.perf_counter(), time.thread_time()
            plan = controller.solve(state, refs, edf)
            ms = (time.perf_counter() - t0) * 1e3
            log.wall_ms.append(ms)
            log.cpu_ms.append((time.thread_time() - c0) * 1e3)
            log.gc_ms.append(gc_timer.total_ms - gc0)
            log.rescued.append(controller.counts.qp_rescues > rescues)
            log.sqp_iterations.append(plan.extras.get("sqp_iterations", 0.0))
            log.qp_iterations.append(plan.extras.get("qp_iterations", 0.0))
            log.qp_ms.append(float(sum(plan.solve_ms)))
            log.hpipm_ms.append(plan.extras.get("hpipm_ms", 0.0))
            log.fallbacks += plan.status in (PlanStatus.FALLBACK, PlanStatus.STOPPING)
            log.over_budget += ms > params.solve_timeout_ms
            one_iteration = not refs.switched and controller.last_step is not None and k > 0
            if reference is not None and (k // 10) % every == every - 1 and one_iteration and plan.status in (
                    PlanStatus.OK, PlanStatus.SLACK):
                compare_with_ipopt(log, reference, controller, state, refs, edf, warm, ms)
        sim.command(plan.velocity_at(state.t), state.t)
        sim.step(0.01)
    gc_timer.close()
    log.qp_failures, log.qp_rescues = controller.counts.qp_failures, controller.counts.qp_rescues
    return log


def floor_figures(log: RunLog) -> dict[str, float]:
    """Where a steady two-level step's time goes: HPIPM's own arithmetic (its iterations times the time per
    iteration), the rest of the QP calls (casadi's argument handling, the Python around each call), and the
    Python outside the QPs (FK, linearisation, EDF lookups, collision rows, assembly, trust region, plan)."""
    wall, qp, hpipm = (np.asarray(log.steady(x)) for x in (log.wall_ms, log.qp_ms, log.hpipm_ms))
    iterations = np.asarray(log.steady(log.qp_iterations))
    if wall.size == 0:
        return {}
    per_iteration = hpipm[iterations > 0] / iterations[iterations > 0]
    return {
        "l2_n10_steady_median_ms": float(np.median(wall)),
        "l2_n10_hpipm_median_ms": float(np.median(hpipm)),
        "l2_n10_qp_call_overhead_median_ms": float(np.median(qp - hpipm)),
        "l2_n10_outside_qp_median_ms": float(np.median(wall - qp)),
        "hpipm_iterations_per_step_median": float(np.median(iterations)),
        "hpipm_ms_per_iteration": float(np.median(per_iteration)) if per_iteration.size else float("nan"),
    }


SWITCH_SPREAD = {"sqp_iters_on_switch": 2, "sqp_switch_carry": 3}
"""The switch's iterations spread over the task's first steps (2 + 2 + 1), the option measured against the default."""


def switch_figures(robot: RobotModel, quick: bool) -> dict[str, float]:
    """A task's first step over >= 10 task switches (bench/task_switch.py), with the default (all of a switch's
    iterations in its first step) and spread over the first steps (`_spread`: `SWITCH_SPREAD`), in one run."""
    repeats = 2 if quick else 3
    base = HTMPCParams(constraint="cbf")
    spread = run_switches(robot, replace(base, **SWITCH_SPREAD), repeats)
    default = run_switches(robot, base, repeats)
    return default.figures() | spread.figures("_spread")


SWITCH_TARGET = "<= 40"
"""A task's first step within one control period at 25 Hz (issue 33: control at 20-25 Hz)."""


def switch_units(figures: dict[str, float]) -> dict[str, str]:
    return {k: "ms" if "_ms_" in k else "s" if k.startswith("switch_sequence_s") else "m" if "_error_" in k else ""
            for k in figures}


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--switches-only", action="store_true",
                        help="only the task switch figures (bench/task_switch.py)")


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0] if __doc__ else "", argv, _options)
    if args.switches_only:
        robot = RobotModel()
        figures = switch_figures(robot, args.quick)
        write_result("htmpc_solve", figures, switch_units(figures), {"first_step_ms_max": SWITCH_TARGET},
                     quick=args.quick)
        return
    seconds = 6.0 if args.quick else 14.0
    every = 3 if args.quick else 1
    load_before = os.getloadavg()[0]
    robot = RobotModel()
    base = HTMPCParams(constraint="cbf")
    l1 = closed_loop(robot, base, 1, seconds, None, every, "1 level, N=10")
    # Timed without IPOPT in between: its ~90 ms of work between our steps evicts the caches and cost our
    # step 0.5-0.7 ms of CPU (median) in one interleaved measurement, a cost no real control loop pays.
    l2 = closed_loop(robot, base, 2, seconds, None, every, "2 levels, N=10")
    vs_ipopt = closed_loop(robot, base, 2, seconds, IpoptReference(robot, base, tol=IPOPT_TOL), every,
                           "2 levels, N=10, beside IPOPT")
    n20 = replace(base, N=20, dt_s=0.15)
    l2n20 = closed_loop(robot, n20, 2, seconds, None, every, "2 levels, N=20")
    priority = priority_figures(robot, 10.0 if args.quick else 15.0)
    switches = switch_figures(robot, args.quick)
    rng = np.random.default_rng(0)
    configurations = [READY_Q] + [robot.random_q(rng) for _ in range(5 if args.quick else 20)]
    cover = cover_gaps(SimWorld(robot), robot, configurations)
    ours_at_ipopt = percentile(vs_ipopt.ours_at_ipopt_ms, 50)
    runs = (l1, l2, vs_ipopt, l2n20)
    figures = {
        "l1_n10_median_ms": percentile(l1.wall_ms, 50),
        "l2_n10_median_ms": percentile(l2.wall_ms, 50),
        "l2_n10_p95_ms": percentile(l2.wall_ms, 95),
        "l2_n10_p99_ms": percentile(l2.wall_ms, 99),
        "l2_n20_median_ms": percentile(l2n20.wall_ms, 50),
        "ipopt_l2_n10_median_ms": percentile(vs_ipopt.ipopt_ms, 50),
        "speedup_vs_ipopt": percentile(vs_ipopt.ipopt_ms, 50) / ours_at_ipopt,
        "cost_gap_pct": percentile([g[1] for g in vs_ipopt.gap_pct], 50),
        "cost_gap_p90_pct": percentile([g[1] for g in vs_ipopt.gap_pct], 90),
        "level1_task_gap_pct": percentile([g[0] for g in vs_ipopt.gap_pct], 50),
        "level1_task_gap_p90_pct": percentile([g[0] for g in vs_ipopt.gap_pct], 90),
        "collision_row_violation_p90": percentile(vs_ipopt.violation, 90),
        "collision_row_violation_max": float(np.max(vs_ipopt.violation)) if vs_ipopt.violation else float("nan"),
        "speedup_vs_ipopt_solver_only": percentile(vs_ipopt.ipopt_solver_ms, 50) / ours_at_ipopt,
        "l2_n10_beside_ipopt_median_ms": ours_at_ipopt,
        "l1_n10_cpu_median_ms": percentile(l1.cpu_ms, 50),
        "l2_n10_cpu_median_ms": percentile(l2.cpu_ms, 50),
        "l2_n10_cpu_p99_ms": percentile(l2.cpu_ms, 99),
        "l2_n20_cpu_median_ms": percentile(l2n20.cpu_ms, 50),
        "l2_n10_max_ms": float(np.max(l2.wall_ms)),
        "solves_l2_n10": float(len(l2.wall_ms)),
        "ipopt_states": float(len(vs_ipopt.ipopt_ms)),
        "fallbacks": float(sum(r.fallbacks for r in runs)),
        "qp_failures": float(sum(r.qp_failures for r in runs)),
        "qp_rescues": float(sum(r.qp_rescues for r in runs)),
        "solves_over_timeout": float(sum(r.over_budget for r in runs)),
        **priority,
        **switches,
        "sphere_cover_gap_m": max(cover.values()),
        **{f"tail_{cause}": float(n) for cause, n in l2.tail_causes().items()},
        "tail_solves": float(np.sum(np.asarray(l2.wall_ms) > TAIL_FACTOR * np.median(l2.wall_ms))),
        "l2_n10_p99_over_median": percentile(l2.wall_ms, 99) / percentile(l2.wall_ms, 50),
        "l2_n10_cpu_p99_over_median": percentile(l2.cpu_ms, 99) / percentile(l2.cpu_ms, 50),
        "l2_n10_steady_p99_ms": percentile(l2.steady(l2.wall_ms), 99),
        **floor_figures(l2),
        "gc_ms_in_solves": float(np.sum(l2.gc_ms)),
        "load_avg_before": load_before,
        "load_avg_after": os.getloadavg()[0],
    }
    units = {k: "ms" for k in figures if k.endswith("_ms")}
    units.update({k: "%" for k in figures if k.endswith("_pct")})
    units.update({"collision_row_violation_p90": "m/s", "collision_row_violation_max": "m/s",
                  "priority_leak_m": "m", "priority_leak_deg": "deg", "level2_gain_min_m": "m",
                  "priority_case_collisions": "", "sphere_cover_gap_m": "m"})
    units.update({"speedup_vs_ipopt": "x", "speedup_vs_ipopt_solver_only": "x", "solves_l2_n10": "",
                  "ipopt_states": "", "fallbacks": "", "qp_failures": "", "qp_rescues": "",
                  "solves_over_timeout": "", "load_avg_before": "", "load_avg_after": "", "l2_n10_p99_over_median": "x",
                  "l2_n10_cpu_p99_over_median": "x", "hpipm_iterations_per_step_median": ""})
    units.update({k: "" for k in figures if k.startswith("tail_")})
    units.update(switch_units(switches))
    targets = {"first_step_ms_max": SWITCH_TARGET, "l2_n10_median_ms": "<= 4", "l2_n10_p99_ms": "<= 10",
               "l2_n20_median_ms": "<= 7",
               "l2_n10_p99_over_median": "<= 2.5", "speedup_vs_ipopt": ">= 25",
               "cost_gap_pct": "<= 1", "priority_leak_m": "<= 0.01", "priority_leak_deg": "<= 1",
               "level2_gain_min_m": "> 0", "sphere_cover_gap_m": "0"}
    write_result("htmpc_solve", figures, units, targets, quick=args.quick)


if __name__ == "__main__":
    main()
