"""Simulation speed: physics real-time factor at 500 Hz with and without the two 10 Hz depth cameras,
ms per depth render, and the cost of scene edits while running (move, add, remove, pool growth).

    python -m bench.sim_rate [--quick]
"""

from __future__ import annotations

import time

import numpy as np

import core.sim  # noqa: F401  (GL backend first)
from bench.report import bench_args, write_result
from core.params import SimParams
from core.robot.model import READY_Q, RobotModel
from core.scene import Box, random_scene
from core.sim.depth_camera import DepthCamera
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld

QDOT = np.array([0.4, 0.1, 0.2, 0.3, -0.2, 0.2, 0.1, 0.1, 0.1])


def _rtf(sim: SimRobot, seconds: float) -> float:
    sim.world.set_robot(READY_Q)
    t0 = time.perf_counter()
    steps = int(seconds / 0.01)
    for _ in range(steps):
        sim.command(QDOT, sim.time)
        sim.step(0.01)
        sim.observe()
    return seconds / (time.perf_counter() - t0)


def _median_ms(fn, n: int) -> float:
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        fn(i)
        samples.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(samples))


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0], argv)
    seconds = 3.0 if args.quick else 20.0
    robot = RobotModel()
    world = SimWorld(robot, SimParams(), random_scene(0))
    physics_rtf = _rtf(SimRobot(world, cameras=()), seconds)
    with_cams = SimRobot(world)
    with_cams.step(0.01)  # create the GL contexts outside the timing
    cameras_rtf = _rtf(with_cams, seconds)
    cam = DepthCamera(world, "hand", SimParams().hand_camera)
    cam.render()
    render_ms = _median_ms(lambda _: cam.render(), 30 if args.quick else 200)

    n_edit = 50 if args.quick else 300
    move_ms = _median_ms(lambda i: world.move_box("box_0", (-1.0 + 0.001 * i, 1.3, 0.3)), n_edit)
    add_ms = _median_ms(lambda i: world.add_box(Box(f"extra_{i}", (20.0 + i, 20.0, 0.3)), check_robot=False), 20)
    remove_ms = _median_ms(lambda i: world.remove_box(f"extra_{i}"), 20)
    grow_world = SimWorld(robot, SimParams(box_pool=32), random_scene(0))
    for i in range(32 - len(grow_world.boxes())):
        grow_world.add_box(Box(f"fill_{i}", (20.0 + i, 20.0, 0.3)), check_robot=False)
    t0 = time.perf_counter()
    grow_world.add_box(Box("overflow", (30.0, 30.0, 0.3)), check_robot=False)
    grow_ms = (time.perf_counter() - t0) * 1e3

    figures = {"physics_rtf": physics_rtf, "physics_with_cameras_rtf": cameras_rtf, "depth_render_ms": render_ms,
               "box_move_ms": move_ms, "box_add_ms": add_ms, "box_remove_ms": remove_ms,
               "box_pool_grow_ms": grow_ms}
    units = {"physics_rtf": "x", "physics_with_cameras_rtf": "x", "depth_render_ms": "ms", "box_move_ms": "ms",
             "box_add_ms": "ms", "box_remove_ms": "ms", "box_pool_grow_ms": "ms"}
    targets = {"physics_with_cameras_rtf": ">= 2"}
    write_result("sim_rate", figures, units, targets, quick=args.quick)


if __name__ == "__main__":
    main()
