"""Strict priority in closed loop: conflicting base and EE goals, both orders, with and without boxes near
the robot (lockstep MuJoCo, ground-truth EDF). Figures for `bench/htmpc_solve.py`:

- `priority_leak_m` / `priority_leak_deg`: the largest steady-state level-1 error (position / angle, worst
  over the last 2 s) minus what level 1 reaches alone (its single-task optimum in the same closed loop);
- `level2_gain_min_m`: the smallest improvement of level 2's final position error over its error when
  nobody optimises it (level 1 alone); positive means level 2 still works.

The cases differ from `tests/core/htmpc/test_priority_closed_loop.py` (other goals, other boxes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

import core.sim  # noqa: F401  (GL backend first)
from core.angles import wrap_angle
from core.htmpc import HTMPC
from core.htmpc.so3 import log3
from core.params import SensorParams
from core.robot.model import READY_Q, RobotModel
from core.scene import Box, Scene
from core.sim.ground_truth import ground_truth_edf
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import BaseReference, EEReference, References

BASE = BaseReference(np.array([[-1.2, 1.4]]), np.array([-2.0]))
EE = EEReference(np.array([[2.0, -1.0, 0.5]]), pin.utils.rpyToMatrix(0.0, np.pi / 2, -0.6)[None])
"""3.8 m apart: no configuration reaches both."""
BOXES = Scene((Box("near_base_goal", (-1.2, 2.55, 0.3)), Box("near_hand_goal", (2.0, -1.9, 0.3)),
               Box("on_the_way", (0.6, 0.9, 0.3))))
SETTLED_S = 2.0


@dataclass(frozen=True)
class CaseResult:
    leak_m: float
    leak_deg: float
    level2_gain_m: float
    collisions: int


def _errors(robot: RobotModel, q: np.ndarray) -> dict[str, np.ndarray]:
    T = robot.ee_pose(q)
    yaw = wrap_angle(BASE.yaw[0] - q[2])
    return {"base": np.array([np.hypot(*(q[:2] - BASE.xy[0])), np.degrees(abs(yaw))]),
            "ee": np.array([np.linalg.norm(T[:3, 3] - EE.position[0]),
                            np.degrees(np.linalg.norm(log3(T[:3, :3].T @ EE.rotation[0])))])}


def _run(robot: RobotModel, order: tuple[str, ...], scene: Scene, seconds: float) -> tuple[list[np.ndarray], int]:
    """Configurations at 10 Hz of a lockstep closed loop toward the references of `order`, and its contacts."""
    world = SimWorld(robot, scene=scene)
    world.set_robot(READY_Q)
    sim = SimRobot(world, cameras=(), sensor=SensorParams.ideal())
    controller = HTMPC(robot)
    controller.enforce_timeout = False
    qs, plan = [], None
    for k in range(int(round(seconds / 0.01))):
        state = sim.observe().state
        if k % 10 == 0:
            refs = References(order, BASE, EE if "ee" in order else None, switched=k == 0)
            plan = controller.solve(state, refs, ground_truth_edf(world.obstacles(), state.q[:2]))
            qs.append(state.q.copy())
        sim.command(plan.velocity_at(state.t), state.t)
        sim.step(0.01)
    return qs, len(world.collisions)


def run_case(robot: RobotModel, order: tuple[str, str], scene: Scene, seconds: float) -> CaseResult:
    first, second = order
    alone, _ = _run(robot, (first,), scene, seconds)
    both, collisions = _run(robot, order, scene, seconds)
    optimum = _errors(robot, alone[-1])[first]
    settled = np.max([_errors(robot, q)[first] for q in both[-int(SETTLED_S * 10):]], axis=0)
    gain = _errors(robot, alone[-1])[second][0] - _errors(robot, both[-1])[second][0]
    return CaseResult(float(settled[0] - optimum[0]), float(settled[1] - optimum[1]), float(gain), collisions)


def priority_figures(robot: RobotModel, seconds: float) -> dict[str, float]:
    """The figures over both orders, without and with boxes."""
    results = [run_case(robot, order, scene, seconds) for order in (("base", "ee"), ("ee", "base"))
               for scene in (Scene(), BOXES)]
    return {"priority_leak_m": max(r.leak_m for r in results),
            "priority_leak_deg": max(r.leak_deg for r in results),
            "level2_gain_min_m": min(r.level2_gain_m for r in results),
            "priority_case_collisions": float(sum(r.collisions for r in results))}
