"""A minimal closed loop for controller tests: MuJoCo physics, 10 Hz HTMPC, 100 Hz commands."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from core.htmpc import HTMPC
from core.params import SensorParams
from core.sim.ground_truth import ground_truth_edf
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import Plan, References, RobotState


@dataclass
class LoopLog:
    t: list[float] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    v: list[np.ndarray] = field(default_factory=list)
    commands: list[np.ndarray] = field(default_factory=list)
    clearance: list[float] = field(default_factory=list)
    plans: list[Plan] = field(default_factory=list)


def run(world: SimWorld, controller: HTMPC, refs: References | Callable[[float], References], seconds: float,
        use_edf: bool = True, before_control: Callable[[SimWorld, RobotState], None] | None = None) -> LoopLog:
    """Drive the world for `seconds`; the EDF is the simulator's exact one around the robot.
    `before_control(world, state)` runs before every control step (a test's scene edits)."""
    controller.enforce_timeout = False  # lockstep: simulated time waits for the solver
    sim = SimRobot(world, cameras=(), sensor=SensorParams.ideal())  # the controller's test: exact odometry
    log = LoopLog()
    plan = None
    steps = int(round(seconds / 0.01))
    for k in range(steps):
        state = sim.observe().state
        if k % 10 == 0:
            if before_control is not None:
                before_control(world, state)
            edf = ground_truth_edf(world.obstacles(), state.q[:2]) if use_edf else None
            r = refs(state.t) if callable(refs) else refs
            if k > 0 and not callable(refs):
                r = References(r.order, r.base, r.ee, switched=False)
            plan = controller.solve(state, r, edf)
            log.plans.append(plan)
            log.t.append(state.t)
            log.q.append(state.q.copy())
            log.v.append(state.v.copy())
            log.clearance.append(world.robot_box_distance()[0])
        qdot = plan.velocity_at(state.t)
        log.commands.append(qdot)
        sim.command(qdot, state.t)
        sim.step(0.01)
    return log
