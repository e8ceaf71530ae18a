"""A task's first control steps: the sequence of two pick-up stops in the default scene, driven back to the start and
repeated, in closed loop on the simulation with the ground-truth EDF (lockstep: the solver's time does not move the
robot), timing every solve and marking the task switches (`References.switched`).

Right after a switch the warm start is the previous task's plan, far from the new one: the controller iterates its
SQP there (`HTMPCParams.sqp_iters_on_switch`), which makes the first step the slowest of a task. Its time must fit
one control period. Beside the times, each task's result: whether it finished, and its error when it did (the
plans' quality must not pay for a faster first step).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from app.runtime.config import DEFAULT_SCENE
from core.htmpc import HTMPC
from core.params import HTMPCParams, SensorParams
from core.robot.model import READY_Q, RobotModel
from core.scene import Scene, load_scene
from core.sim.ground_truth import ground_truth_edf
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import PlanStatus
from tasks import BasePose, BaseSubtask, Subtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR, load_sequence
from tasks.sequencer import Outcome, Sequencer

STEP_S = 0.01
"""Command period (s): the plan is followed at 100 Hz between control steps."""
FOLLOWING = 3
"""Steps after a task's first that `following_steps` reports (where the switch's carried iterations go)."""


@dataclass
class SwitchLog:
    """Per solve: wall ms, SQP iterations, whether it was a task's first step; per task: its outcome."""

    wall_ms: list[float] = field(default_factory=list)
    cpu_ms: list[float] = field(default_factory=list)
    """The solving thread's CPU time per solve: the wall time less any wait for the core (the machine is shared)."""
    sqp_iterations: list[float] = field(default_factory=list)
    switched: list[bool] = field(default_factory=list)
    outcomes: list[str] = field(default_factory=list)
    errors_m: list[float] = field(default_factory=list)
    """Each task's position error when it ended (m)."""
    fallbacks: int = 0

    sim_s: float = 0.0
    """Simulated time the sequence took (s)."""

    def first_steps(self, values: list[float]) -> list[float]:
        """`values` of the tasks' first steps."""
        return [x for x, s in zip(values, self.switched, strict=True) if s]

    def following_steps(self, values: list[float], n: int = FOLLOWING) -> list[float]:
        """`values` of the `n` steps after each task's first."""
        first = np.flatnonzero(self.switched)
        return [values[i] for f in first for i in range(f + 1, min(f + 1 + n, len(values)))]

    def figures(self, suffix: str = "") -> dict[str, float]:
        first, following = self.first_steps(self.wall_ms), self.following_steps(self.wall_ms)
        return {f"first_step_ms_max{suffix}": max(first, default=float("nan")),
                f"first_step_ms_p50{suffix}": float(np.median(first)) if first else float("nan"),
                f"first_step_cpu_ms_max{suffix}": max(self.first_steps(self.cpu_ms), default=float("nan")),
                f"following_steps_ms_max{suffix}": max(following, default=float("nan")),
                f"following_steps_cpu_ms_max{suffix}": max(self.following_steps(self.cpu_ms), default=float("nan")),
                f"first_step_sqp_iterations_p50{suffix}": float(np.median(self.first_steps(self.sqp_iterations))),
                f"task_switches{suffix}": float(len(first)),
                f"switch_tasks_done{suffix}": float(self.outcomes.count("done")),
                f"switch_tasks{suffix}": float(len(self.outcomes)),
                f"switch_sequence_s{suffix}": self.sim_s,
                f"switch_task_error_max_m{suffix}": float(np.nanmax(self.errors_m)) if self.errors_m else float("nan"),
                f"switch_fallbacks{suffix}": float(self.fallbacks)}


def switching_sequence(repeats: int) -> tuple[Scene, TaskSequence]:
    """Two pick-up stops and the drive back to the start, `repeats` times (4 + 1 tasks a round)."""
    base = load_sequence(EXAMPLES_DIR / "two_pickups.yaml")
    scene = load_scene(DEFAULT_SCENE)
    home = BaseSubtask(name="back to the start", target=BasePose(x=0.0, y=0.0, yaw_deg=0.0), timeout_s=60.0)
    subtasks: list[Subtask] = []
    for _ in range(repeats):
        subtasks += [*base.subtasks, home]
    return scene, TaskSequence(name="switching", subtasks=subtasks)


def run_switches(robot: RobotModel, params: HTMPCParams, repeats: int, max_s: float = 600.0) -> SwitchLog:
    """Drive the sequence to its end (or `max_s` of simulated time); time every solve."""
    scene, seq = switching_sequence(repeats)
    world = SimWorld(robot, scene=scene)
    q0 = READY_Q.copy()
    q0[:3] = scene.robot_start
    world.set_robot(q0)
    sim = SimRobot(world, cameras=(), sensor=SensorParams.ideal())
    sequencer = Sequencer(robot, seq, n_nodes=params.N, dt=params.dt_s)
    controller = HTMPC(robot, params)
    controller.enforce_timeout = False  # lockstep: the solver's time must not change the run
    occupied = np.concatenate([np.random.default_rng(0).uniform(-0.5, 0.5, (300, 3)) * b.size + b.position
                               for b in scene.boxes])
    per_control = int(round(1.0 / (params.control_rate_hz * STEP_S)))
    log, plan = SwitchLog(), None
    for k in range(int(max_s / STEP_S)):
        state = sim.observe().state
        if k % per_control == 0:
            refs = sequencer.update(state, occupied, state.t)
            if refs is None:
                break
            edf = ground_truth_edf(world.obstacles(), state.q[:2])
            t0, c0 = time.perf_counter(), time.thread_time()
            plan = controller.solve(state, refs, edf)
            log.wall_ms.append((time.perf_counter() - t0) * 1e3)
            log.cpu_ms.append((time.thread_time() - c0) * 1e3)
            log.sqp_iterations.append(plan.extras.get("sqp_iterations", 0.0))
            log.switched.append(refs.switched)
            log.fallbacks += plan.status in (PlanStatus.FALLBACK, PlanStatus.STOPPING)
        assert plan is not None
        sim.command(plan.velocity_at(state.t), state.t)
        sim.step(STEP_S)
    log.outcomes = [Outcome(p.outcome).value for p in sequencer.progress]
    log.errors_m = [p.position_error_m for p in sequencer.progress]
    log.sim_s = world.time
    return log
