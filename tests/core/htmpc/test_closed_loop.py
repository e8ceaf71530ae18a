"""The controller in closed loop with MuJoCo: reaching, and driving toward a wall of boxes."""

import numpy as np
import pinocchio as pin
import pytest

from core.htmpc import HTMPC
from core.htmpc.so3 import log3
from core.params import HTMPCParams
from core.robot.model import READY_Q
from core.scene import Box, Scene
from core.sim.world import SimWorld
from core.types import BaseReference, EEReference, References
from tests.core.htmpc.closed_loop import run


def test_ee_reach_converges(robot):
    world = SimWorld(robot, scene=Scene())
    world.set_robot(READY_Q)
    Rd = pin.utils.rpyToMatrix(0.0, np.pi / 2, 0.3)  # tool pointing down, turned 17°
    target = np.array([1.1, 0.35, 0.7])
    refs = References(order=("ee", "base"), base=BaseReference(np.zeros((1, 2)), np.zeros(1)),
                      ee=EEReference(target[None], Rd[None]), switched=True)
    log = run(world, HTMPC(robot), refs, 8.0, use_edf=False)
    T = robot.ee_pose(world.state().q)
    assert np.linalg.norm(T[:3, 3] - target) < 0.01
    assert np.degrees(np.linalg.norm(log3(T[:3, :3].T @ Rd))) < 1.0
    assert all(p.status.value in ("ok", "ok_with_slack") for p in log.plans)


def test_base_reach_converges(robot):
    world = SimWorld(robot, scene=Scene())
    world.set_robot(READY_Q)
    refs = References(order=("base", "ee"), base=BaseReference(np.array([[1.5, -1.0]]), np.array([0.8])),
                      switched=True)
    run(world, HTMPC(robot), refs, 8.0, use_edf=False)
    q = world.state().q
    assert np.hypot(q[0] - 1.5, q[1] + 1.0) < 0.01
    assert abs(np.degrees(q[2] - 0.8)) < 1.0


WALL = Scene(tuple(Box(f"wall_{i}", (3.0, y, 0.3)) for i, y in enumerate(np.arange(-1.8, 1.81, 0.6))))
DRIVE = References(order=("base",), base=BaseReference(np.array([[6.0, 0.0]]), np.zeros(1)), switched=True)


def drive_to_wall(robot, **params):
    world = SimWorld(robot, scene=WALL)
    world.set_robot(READY_Q)
    log = run(world, HTMPC(robot, HTMPCParams(**params)), DRIVE, 8.0)
    return world, log


@pytest.fixture(scope="module")
def wall_runs(robot):
    runs = {("cbf", g): drive_to_wall(robot, constraint="cbf", gamma=g) for g in (0.3, 1.0, 3.0)}
    runs[("edf", None)] = drive_to_wall(robot, constraint="edf")
    return runs


def test_cbf_and_edf_stay_collision_free(wall_runs):
    for key, (world, log) in wall_runs.items():
        assert world.collisions == [], key
        assert min(log.clearance) > 0.0, key
        assert all(np.all(np.isfinite(c)) for c in log.commands)


def test_smaller_gamma_keeps_more_clearance(wall_runs):
    clearance = [min(wall_runs[("cbf", g)][1].clearance) for g in (0.3, 1.0, 3.0)]
    assert clearance[0] > clearance[1] > clearance[2], clearance


def speed_near_wall(log, distance_m: float) -> float:
    """Base speed when the robot–box distance first drops below `distance_m`."""
    for c, v in zip(log.clearance, log.v, strict=True):
        if c < distance_m:
            return float(np.hypot(v[0], v[1]))
    return float("nan")


def test_cbf_slows_down_near_obstacles_more_than_edf(wall_runs):
    cbf = wall_runs[("cbf", 1.0)][1]
    edf = wall_runs[("edf", None)][1]
    assert speed_near_wall(cbf, 0.6) < speed_near_wall(edf, 0.6)
    assert min(cbf.clearance) > min(edf.clearance)


def test_hand_held_beside_the_base_while_it_drives(robot):
    """A base-frame EE reference: the hand goes beside the base and stays there while the base drives 3 m and
    turns. The same pose given as a world target at the start pose would pull the hand back to where it was."""
    world = SimWorld(robot, scene=Scene())
    world.set_robot(READY_Q)
    Rb = pin.utils.rpyToMatrix(0.0, 0.0, -np.pi / 2)
    pb = np.array([0.4, -0.55, 1.0])

    def refs(t: float) -> References:
        s = min(0.5 * max(t - 4.0, 0.0), 3.0)  # the arm settles, then the base drives 3 m at 0.5 m/s, turning 45°
        return References(order=("base", "ee"), base=BaseReference(np.array([[s, 0.0]]), np.array([np.pi / 4 * s / 3])),
                          ee=EEReference(pb[None], Rb[None], frame="base"), switched=t == 0.0)

    log = run(world, HTMPC(robot), refs, 11.0, use_edf=False)
    errors = []
    for t, q in zip(log.t, log.q, strict=True):
        T_rel = np.linalg.inv(robot.frame_pose(q, "mobile_base")) @ robot.ee_pose(q)
        errors.append((t, np.linalg.norm(T_rel[:3, 3] - pb), np.degrees(np.linalg.norm(log3(T_rel[:3, :3].T @ Rb)))))
    driving = [(e, a) for t, e, a in errors if t > 4.0]
    assert max(e for e, _ in driving) < 0.02 and max(a for _, a in driving) < 2.0
    q = world.state().q
    assert np.hypot(q[0] - 3.0, q[1]) < 0.05 and abs(q[2] - np.pi / 4) < 0.05
    assert all(p.status.value in ("ok", "ok_with_slack") for p in log.plans)
