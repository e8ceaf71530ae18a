"""HTMPC solve time over a closed-loop navigation run (CBF on, all 14 spheres, ground-truth EDF):
1 and 2 levels at N = 10, 2 levels at N = 20, and the IPOPT reference on the same states in the same
run (speed ratio and cost gap).

    python -m bench.htmpc_solve [--quick]
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from rich.progress import track

import core.sim  # noqa: F401  (GL backend first)
from bench.report import bench_args, percentile, write_result
from core.htmpc import HTMPC
from core.htmpc.ipopt_reference import IpoptReference
from core.params import HTMPCParams
from core.robot.model import READY_Q, RobotModel
from core.sim.ground_truth import ground_truth_edf
from core.sim.scene import random_scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import References
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.sequencer import Sequencer


def closed_loop(robot: RobotModel, params: HTMPCParams, levels: int, seconds: float, reference: IpoptReference | None,
                every: int, label: str) -> dict[str, list[float]]:
    """Drive the paper's random scene; time every solve; compare with IPOPT every `every` steps."""
    scene = random_scene(0)
    world = SimWorld(robot, scene=scene)
    q0 = READY_Q.copy()
    q0[:3] = scene.robot_start
    world.set_robot(q0)
    sim = SimRobot(world, cameras=())
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=scene.goal[0], y=scene.goal[1], yaw_deg=0.0),
                                             timeout_s=1e3)])
    sequencer = Sequencer(robot, seq, n_nodes=params.N, dt=params.dt_s)
    controller = HTMPC(robot, params)
    occupied = np.concatenate([np.random.default_rng(0).uniform(-0.5, 0.5, (300, 3)) * b.size + b.position
                               for b in scene.boxes])
    out: dict[str, list[float]] = {"ours_ms": [], "ipopt_ms": [], "gap1_pct": [], "gap_last_pct": [],
                                   "ours_state_ms": []}
    plan = None
    steps = int(seconds / 0.01)
    for k in track(range(steps), description=label, transient=True):
        state = sim.observe().state
        if k % 10 == 0:
            refs = sequencer.update(state, occupied, state.t)
            if refs is None:
                break
            if levels == 1:
                refs = References(order=refs.order[:1], base=refs.base, ee=None, switched=refs.switched)
            edf = ground_truth_edf(world.obstacles(), state.q[:2])
            warm = controller.warm_start(state)
            t0 = time.perf_counter()
            plan = controller.solve(state, refs, edf)
            ms = (time.perf_counter() - t0) * 1e3
            out["ours_ms"].append(ms)
            if reference is not None and (k // 10) % every == every - 1:
                res = reference.solve(state, refs, edf, warm.q, warm.v, warm.a, compare=(plan.q, plan.v, plan.u))
                if res.success:
                    out["ipopt_ms"].append(sum(res.level_ms))
                    out["ours_state_ms"].append(ms)
                    gaps = [100.0 * (o - r) / max(abs(r), 1e-9) for o, r in
                            zip(res.compared_costs, res.level_costs, strict=True)]
                    out["gap1_pct"].append(gaps[0])
                    out["gap_last_pct"].append(gaps[-1])
        sim.command(plan.velocity_at(state.t), state.t)
        sim.step(0.01)
    return out


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0], argv)
    seconds = 6.0 if args.quick else 25.0
    every = 4 if args.quick else 2
    robot = RobotModel()
    base = HTMPCParams(constraint="cbf")
    l1 = closed_loop(robot, base, 1, seconds, None, every, "1 level, N=10")
    l2 = closed_loop(robot, base, 2, seconds, IpoptReference(robot, base), every, "2 levels, N=10 (+ IPOPT)")
    n20 = replace(base, N=20, dt_s=0.15)
    l2n20 = closed_loop(robot, n20, 2, seconds, None, every, "2 levels, N=20")
    figures = {
        "l1_n10_median_ms": percentile(l1["ours_ms"], 50),
        "l2_n10_median_ms": percentile(l2["ours_ms"], 50),
        "l2_n10_p95_ms": percentile(l2["ours_ms"], 95),
        "l2_n10_p99_ms": percentile(l2["ours_ms"], 99),
        "l2_n20_median_ms": percentile(l2n20["ours_ms"], 50),
        "ipopt_l2_n10_median_ms": percentile(l2["ipopt_ms"], 50),
        "speedup_vs_ipopt": percentile(l2["ipopt_ms"], 50) / percentile(l2["ours_state_ms"], 50),
        "cost_gap_pct": percentile(l2["gap1_pct"], 50),
        "cost_gap_level2_pct": percentile(l2["gap_last_pct"], 50),
        "cost_gap_p90_pct": percentile(l2["gap1_pct"], 90),
        "solves_l2_n10": float(len(l2["ours_ms"])),
        "ipopt_states": float(len(l2["ipopt_ms"])),
    }
    units = {k: "ms" for k in figures if k.endswith("_ms")}
    units.update({"speedup_vs_ipopt": "x", "cost_gap_pct": "%", "cost_gap_level2_pct": "%", "cost_gap_p90_pct": "%",
                  "solves_l2_n10": "", "ipopt_states": ""})
    targets = {"l2_n10_median_ms": "<= 10", "l2_n10_p99_ms": "<= 25", "speedup_vs_ipopt": ">= 4",
               "cost_gap_pct": "<= 1"}
    write_result("htmpc_solve", figures, units, targets, quick=args.quick)


if __name__ == "__main__":
    main()
