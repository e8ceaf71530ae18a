"""The base path's re-plan, the part of a control step that follows a change of the map: the occupancy grid the
sequencer plans on (`OccupancyGrid.from_points` at the preferred inflation, 3 sub-cells a side), A* through the
goal and the line-of-sight shortcut (`tasks.path_planner.plan_path`), and the cheap grid every control step builds
to notice a change (1 sub-cell).

Cases: the shipped scenes (default, aisle) and the paper's random scenes, each box's volume sampled as the map's
occupied points, from the scene's robot start to goals drawn over the planning bounds (`SequencerParams`). A
re-plan happens in the control step that first sees a box appear (`bench/reaction_chain.py`'s `references` part),
so its tail adds to the reaction.

    python -m bench.path_planning [--quick]
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from app.runtime.config import DEFAULT_SCENE
from bench.report import bench_args, percentile, write_result
from core.params import SequencerParams
from core.scene import Scene, load_scene, random_scene
from tasks.occupancy import OccupancyGrid
from tasks.path_planner import NoPathError, astar, plan_path

log = logging.getLogger(__name__)

AISLE_SCENE = DEFAULT_SCENE.parent / "aisle.yaml"
POINTS_PER_BOX = 300
GOALS_PER_SCENE = {True: 4, False: 12}
RANDOM_SCENES = {True: 6, False: 40}


@dataclass(frozen=True)
class Case:
    """One re-plan: the map's occupied points (world, P×3), where the base stands, where it goes."""

    occupied: np.ndarray
    start_xy: np.ndarray
    goal_xy: np.ndarray


def scene_points(scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """Points filling each box's volume, as a map's occupied points would."""
    return np.concatenate([rng.uniform(-0.5, 0.5, (POINTS_PER_BOX, 3)) * b.size + b.position for b in scene.boxes])


def cases(quick: bool, params: SequencerParams) -> list[Case]:
    """Start-goal pairs over the shipped and random scenes (fixed seeds)."""
    rng = np.random.default_rng(0)
    scenes = [load_scene(DEFAULT_SCENE), load_scene(AISLE_SCENE)]
    scenes += [random_scene(seed, n_boxes=10) for seed in range(RANDOM_SCENES[quick])]
    x0, x1, y0, y1 = params.plan_bounds_m
    out = []
    for scene in scenes:
        occupied = scene_points(scene, rng)
        for _ in range(GOALS_PER_SCENE[quick]):
            goal = rng.uniform([x0 + 0.5, y0 + 0.5], [x1 - 0.5, y1 - 0.5])
            out.append(Case(occupied, np.array(scene.robot_start[:2], float), goal))
    return out


def timed_ms(fn, *args, **kwargs) -> tuple[float, object]:
    """Wall ms of one call and its result (a `NoPathError` is a result too: a refusal costs the same search)."""
    t0 = time.perf_counter()
    try:
        result = fn(*args, **kwargs)
    except NoPathError as err:
        result = err
    return (time.perf_counter() - t0) * 1e3, result


def measure(quick: bool) -> dict[str, float]:
    """Per case: the change grid, the planning grid, `plan_path` on it (A*, shortcut, resampling), A* alone, and the
    whole re-plan (grid + `plan_path`)."""
    p = SequencerParams()
    change, grid_ms, astar_ms, path_ms, plan_ms = [], [], [], [], []
    refused = 0
    for case in tqdm(cases(quick, p), desc="re-plans", leave=False):
        ms, _ = timed_ms(OccupancyGrid.from_points, case.occupied, p.plan_bounds_m, p.grid_cell_m, p.inflation_m,
                         p.obstacle_z_m, subcells=1)
        change.append(ms)
        t0 = time.perf_counter()
        ms, grid = timed_ms(OccupancyGrid.from_points, case.occupied, p.plan_bounds_m, p.grid_cell_m,
                            p.inflation_m, p.obstacle_z_m)
        assert isinstance(grid, OccupancyGrid)
        grid_ms.append(ms)
        ms, path = timed_ms(plan_path, grid, case.start_xy, [case.goal_xy])
        path_ms.append(ms)
        plan_ms.append((time.perf_counter() - t0) * 1e3)
        refused += isinstance(path, NoPathError)
        start, goal = grid.cell(case.start_xy), grid.cell(case.goal_xy)
        if not (grid.blocked[start] or grid.blocked[goal]):
            astar_ms.append(timed_ms(astar, grid, start, goal)[0])
    return {"replan_ms_p50": percentile(plan_ms, 50), "replan_ms_p95": percentile(plan_ms, 95),
            "replan_ms_max": max(plan_ms), "plan_grid_ms_p50": percentile(grid_ms, 50),
            "plan_path_ms_p50": percentile(path_ms, 50), "plan_path_ms_p95": percentile(path_ms, 95),
            "astar_ms_p50": percentile(astar_ms, 50), "astar_ms_p95": percentile(astar_ms, 95),
            "change_grid_ms_p50": percentile(change, 50), "replans": float(len(plan_ms)),
            "replans_without_path": float(refused)}


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0] if __doc__ else "", argv)
    figures = measure(args.quick)
    units = {k: "ms" for k in figures if "_ms" in k} | {"replans": "count", "replans_without_path": "count"}
    write_result("path_planning", figures, units, {"replan_ms_p95": "<= 20"}, quick=args.quick)


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO)
    main()
