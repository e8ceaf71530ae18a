"""What the experiments measure on a finished (or running) closed loop, from the simulator's ground truth.

- `run_metrics`: outcome, collisions, clearance, time, path length, speed near obstacles of a run, and the
  controller's failures (`solver_metrics`, summed over trials by `solver_figures`);
- `body_distance`: signed distance from one body group (base, arm, EE) to the nearest box (MuJoCo);
- `collision_bodies`: which body groups touched a box;
- `phantoms`: boxes taken away whose old place the map still holds as occupied;
- `in_view`, `box_in_view`: whether a depth frame sees a point or any corner of a box.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from app.runtime.run_log import RunLog
from app.runtime.snapshot import RunState
from core.htmpc.htmpc import SolveCounts
from core.scene import Box
from core.sim.world import CollisionEvent, SimWorld
from core.types import DepthFrame

BODY_GROUPS: dict[str, tuple[str, ...]] = {
    "base": ("base_body", "base_rack"),
    "arm": ("geom_base_link", "geom_shoulder_link", "geom_upper_arm_link", "geom_forearm_link",
            "geom_wrist_1_link", "geom_wrist_2_link", "geom_wrist_3_link"),
    "ee": ("geom_wrist_1_link", "geom_wrist_2_link", "geom_wrist_3_link"),
}
"""MuJoCo geoms of each body group: the Ridgeback body and rack, the UR10 links, its wrists (the EE)."""
NEAR_OBSTACLE_M = 0.6
"""Clearance under which a control period counts as 'near an obstacle' (speed there is reported)."""
PHANTOM_MIN_POINTS = 3
"""A moved box's old place holding at least this many occupied map points is a phantom."""
PHANTOM_MARGIN_M = 0.1
"""Map points this far outside a box's old footprint still count for it (voxel and EDF rounding)."""


def body_distance(world: SimWorld, group: str, boxes: tuple[Box, ...] | None = None,
                  cutoff_m: float = 5.0) -> float:
    """Smallest signed distance (m) between the geoms of `group` and the given (default: all) boxes."""
    box_ids = None if boxes is None else {b.id for b in boxes}
    return world.robot_box_distance(BODY_GROUPS[group], box_ids, cutoff_m)[0]


def body_reach_m(world: SimWorld, group: str, q: np.ndarray) -> float:
    """How far the geoms of `group` reach ahead of the base centre along the base heading (m).

    Each geom counts by its bounding box (MuJoCo's local AABB, turned into the world)."""
    m, d = world.model, world.data
    heading = np.array([math.cos(q[2]), math.sin(q[2]), 0.0])
    reach = 0.0
    with world.lock:
        for name in BODY_GROUPS[group]:
            g = m.geom(name).id
            R = d.geom_xmat[g].reshape(3, 3)
            centre = d.geom_xpos[g] + R @ m.geom_aabb[g][:3] - np.array([q[0], q[1], 0.0])
            reach = max(reach, float(centre @ heading + np.abs(R.T @ heading) @ m.geom_aabb[g][3:]))
    return reach


def collision_bodies(events: list[CollisionEvent]) -> dict[str, int]:
    """Contact events per body group (a physics step with contact is one event; 500 per second)."""
    counts = dict.fromkeys(("base", "arm"), 0)
    for e in events:
        counts["base" if e.robot_geom in BODY_GROUPS["base"] else "arm"] += 1
    return counts


def _approach_figures(rates: np.ndarray) -> dict[str, float]:
    """Mean of the approach (receding counts as zero), its 90th percentile and maximum, near obstacles."""
    if not len(rates):
        return {"approach_speed_mps": math.nan, "approach_speed_p90_mps": math.nan, "approach_speed_max_mps": math.nan}
    return {"approach_speed_mps": float(np.maximum(rates, 0.0).mean()),
            "approach_speed_p90_mps": float(np.percentile(rates, 90)), "approach_speed_max_mps": float(rates.max())}


def solver_metrics(counts: SolveCounts) -> dict[str, int]:
    """The controller's failures during a run: QPs failed even in HPIPM's rescue mode (any level), stalled QPs
    rescued, exceptions inside the solve, other braking fallbacks."""
    return {"qp_failures": counts.qp_failures, "qp_level1_failures": counts.level1_qp_failures,
            "qp_rescues": counts.qp_rescues, "controller_exceptions": counts.exceptions,
            "controller_solves": counts.solves}


def solver_figures(results: list[dict]) -> dict[str, float]:
    """`solver_metrics` summed over the trials (trials without them count as none)."""
    keys = ("qp_failures", "qp_level1_failures", "qp_rescues", "controller_exceptions", "controller_solves")
    return {k: float(sum(r.get(k, 0) for r in results)) for k in keys}


def approach_speeds(log: RunLog, near_m: float = NEAR_OBSTACLE_M) -> np.ndarray:
    """How fast the clearance shrank (m/s, positive approaching) over each control period that began with the
    clearance under `near_m`: −d/dt of the true robot–box distance, i.e. the velocity of the robot's closest
    point projected on −∇EDF (the paper's approach velocity, Fig. 7b), not the robot's total speed."""
    d, t = np.array(log.min_distance_m, float), np.array(log.t, float)
    if len(d) < 2:
        return np.zeros(0)
    rate = -np.diff(d) / np.maximum(np.diff(t), 1e-9)
    near = np.isfinite(d[:-1]) & np.isfinite(d[1:]) & (d[:-1] < near_m)
    return rate[near]


def run_metrics(run_state: RunState, log: RunLog, events: list[CollisionEvent],
                counts: SolveCounts | None = None) -> dict[str, float | bool]:
    """Figures of one run: finished, collision-free, clearance, time, path length, speeds, and with the
    controller's `counts` its failures."""
    summary = log.summary()
    dist = np.array(log.min_distance_m, float)
    speed = np.array([math.hypot(v[0], v[1]) for v in log.v]) if log.v else np.zeros(0)
    near = np.isfinite(dist) & (dist < NEAR_OBSTACLE_M)
    bodies = collision_bodies(events)
    return {
        "finished": run_state == RunState.FINISHED,
        "collision_free": not events,
        "collision_events": len(events),
        "collision_boxes": len({e.box_id for e in events}),
        "base_collision_events": bodies["base"],
        "arm_collision_events": bodies["arm"],
        "max_penetration_m": max((e.depth_m for e in events), default=0.0),
        "min_clearance_m": summary["min_clearance_m"],
        "duration_s": summary["duration_s"],
        "path_length_m": summary["base_path_length_m"],
        "mean_speed_mps": summary["mean_base_speed_mps"],
        "speed_near_obstacles_mps": float(speed[near].mean()) if near.any() else math.nan,
        **_approach_figures(approach_speeds(log)),
        "solve_ms_median": summary["solve_ms_median"],
        "fallback_steps": summary["fallback_steps"],
        **(solver_metrics(counts) if counts is not None else {}),
    }


@dataclass(frozen=True)
class PhantomCount:
    """Moved boxes whose old place the map still holds, and how many map points are there."""

    count: int
    points: int
    ids: tuple[str, ...]


def _inside(points: np.ndarray, box: Box, margin_m: float) -> np.ndarray:
    """Mask of points within the box grown by `margin_m` (x, y in the box frame, z as is)."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    dx, dy = points[:, 0] - box.position[0], points[:, 1] - box.position[1]
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    dz = points[:, 2] - box.position[2]
    half = np.array(box.size) / 2 + margin_m
    return (np.abs(lx) <= half[0]) & (np.abs(ly) <= half[1]) & (np.abs(dz) <= half[2])


def phantoms(occupied: np.ndarray, moved_from: tuple[Box, ...], present: tuple[Box, ...],
             margin_m: float = PHANTOM_MARGIN_M, min_points: int = PHANTOM_MIN_POINTS) -> PhantomCount:
    """Count the boxes of `moved_from` (old poses) whose place still holds occupied map points.

    Points explained by a box that is really there now (`present`, grown by the margin) are not
    phantoms, so a box moved onto another's old place is not counted.
    """
    pts = np.asarray(occupied, float).reshape(-1, 3)
    for box in present:
        if len(pts):
            pts = pts[~_inside(pts, box, margin_m)]
    ids, total = [], 0
    for box in moved_from:
        n = int(_inside(pts, box, margin_m).sum()) if len(pts) else 0
        if n >= min_points:
            ids.append(box.id)
            total += n
    return PhantomCount(len(ids), total, tuple(ids))


def in_view(frame: DepthFrame, point: np.ndarray, range_m: float = 3.0) -> bool:
    """True if `point` projects inside the frame's image, in front of the camera and within range."""
    p = np.linalg.inv(frame.T_world_camera) @ np.append(point, 1.0)
    if not (0.1 < p[2] <= range_m):
        return False
    u, v, _ = frame.K @ (p[:3] / p[2])
    h, w = frame.depth.shape
    return bool(0.0 <= u < w and 0.0 <= v < h)


def box_in_view(frames: Iterable[DepthFrame], box: Box, range_m: float = 3.0) -> bool:
    """True if any corner of `box` is in view of any of the frames."""
    corners = [box.pose() @ np.array([sx * box.size[0], sy * box.size[1], sz * box.size[2], 2.0]) / 2.0
               for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    return any(in_view(f, c[:3], range_m) for f in frames for c in corners)
