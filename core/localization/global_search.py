"""Global search: where the base is, when the estimate has jumped (a slip, a kidnap) and local registration from
the estimate no longer finds it (docs/method.md, "State estimation", "Lost").

One frame (posed in the world by the current estimate, at its exposure) against the reference (floor and trusted
surfaces, `reference.py`):
  1. initial guesses on a grid around the estimate: offsets (dx, dy) along the base's axes within ±`search_xy_m`
     at `search_step_m`, and dψ within ±`search_yaw_rad` at `search_yaw_step_rad` (9 × 9 × 7 by default);
  2. each guess is scored without registration by the share of the frame's points above the floor that lie within
     `search_coarse_m` of an object surface (the floor fits every guess, so it is not scored);
  3. the best guesses (`search_refined`, at most one per grid neighbourhood, so that equally good places far apart
     all get their turn) are registered by GICP against floor and surfaces, and each result is scored again, by
     the share within `search_inlier_m`;
  4. the best result is accepted only if it is unique: its score at least `search_min_score`, and every result at
     a distinct pose (farther than `search_distinct_m` / `search_distinct_rad` from it) at least `search_margin`
     below it. Along a uniform wall every guess fits alike: no unique answer. Registrations that run off the
     searched window are left out. Whether the estimate itself fits about as well as the best guess
     (`SearchResult.estimate_fits`) is reported too: the caller's way out of a false alarm. So is a search whose
     good fits all lie on one line through the estimate at its heading (`SearchResult.corridor`): the view cannot
     tell a place along that line, and across it and in heading the estimate agrees with them.
Deterministic (one thread, a fixed grid, stable sorts), so lockstep runs repeat.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from core.angles import wrap_angle
from core.localization import registration, se2
from core.localization.reference import FLOOR_ID, Reference
from core.params import LocalizationParams

ABOVE_FLOOR_M = 0.1
"""Points higher than this (m, in the world, whatever the planar guess) are scored; lower ones are floor (depth
noise at 3 m is about 4.5 cm)."""
LOW_FIT = "best fit"
"""How the reason of a search whose best registered guess scored under `search_min_score` begins."""
MIN_SCORED_POINTS = 50
"""A frame with fewer points above the floor cannot be searched with."""


@dataclass(frozen=True)
class Candidate:
    """One registered guess: the base's world pose at the frame's exposure it ends at, its score (share of the
    points above the floor within `search_inlier_m` of a surface), the guess's own score and offset."""

    pose: np.ndarray
    score: float
    coarse: float
    offset: np.ndarray


@dataclass(frozen=True)
class SearchResult:
    """A search's outcome: `unique` and the best candidate (the base's pose to re-anchor at), the best distinct
    runner-up (None: none registered elsewhere), how many guesses were scored and registered, the wall time, and
    why it failed (empty when unique)."""

    unique: bool
    best: Candidate | None
    runner_up: Candidate | None
    guesses: int
    refined: int
    ms: float
    reason: str = ""
    estimate_fits: bool = False
    """The estimate itself (the guess at zero offset) scores within `search_margin` of the best guess before
    registration, or the search is a `corridor` one: whatever disagreed, the frame fits where the estimate puts it
    about as well as anywhere searched."""
    corridor: bool = False
    """Not unique, but every registered guess within `search_margin` of the best lies on one line with the estimate,
    at its heading (`_on_one_line`): along a uniform wall the view constrains the pose across the aisle and in heading,
    and there the estimate agrees; along the aisle nothing in view can tell, so neither can a re-anchoring."""

    @property
    def fits(self) -> bool:
        """Some registered guess fits the reference (scores at least `search_min_score`); False: the reference does not
        describe this view anywhere in the window."""
        return self.best is not None and not self.reason.startswith(LOW_FIT)

    @property
    def margin(self) -> float:
        """Best score minus the runner-up's (the best's own score without a runner-up; nan without a best)."""
        if self.best is None:
            return math.nan
        return self.best.score - (self.runner_up.score if self.runner_up is not None else 0.0)


def offsets(p: LocalizationParams) -> np.ndarray:
    """The grid of guesses (G × 3: dx, dy along the base's axes in m, dψ in rad), the estimate itself included."""
    n_xy = int(round(p.search_xy_m / p.search_step_m))
    n_yaw = int(round(p.search_yaw_rad / p.search_yaw_step_rad))
    xy = p.search_step_m * np.arange(-n_xy, n_xy + 1)
    yaw = p.search_yaw_step_rad * np.arange(-n_yaw, n_yaw + 1)
    gx, gy, gyaw = np.meshgrid(xy, xy, yaw, indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel(), gyaw.ravel()])


def search(ref: Reference, target: registration.Target, source, T_world_camera: np.ndarray, base_pose: np.ndarray,
           p: LocalizationParams) -> SearchResult:
    """Search for the base's pose: `source` the frame's thinned points (camera frame, a small_gicp cloud),
    `T_world_camera` the camera's pose by the current estimate, `base_pose` the base's (x, y, yaw) by it then."""
    t0 = time.perf_counter()
    grid = offsets(p)
    objects = ref.points[ref.object_ids != FLOOR_ID]
    pts = np.asarray(source.points())[:, :3]
    world = pts @ T_world_camera[:3, :3].T + T_world_camera[:3, 3]
    above = world[world[:, 2] > ABOVE_FLOOR_M]

    def fail(reason: str, guesses: int = 0) -> SearchResult:
        return SearchResult(False, None, None, guesses, 0, (time.perf_counter() - t0) * 1e3, reason)

    if len(objects) < MIN_SCORED_POINTS:
        return fail("no trusted surface in view to search against")
    if len(above) < MIN_SCORED_POINTS:
        return fail(f"{len(above)} points above the floor in the frame (< {MIN_SCORED_POINTS})")
    surfaces = registration.Target(objects)
    base_pose = np.asarray(base_pose, float)
    motions = [_motion(base_pose, o) for o in grid]
    coarse = np.array([_score(surfaces, above, D, p.search_coarse_m) for D in motions])
    zero = int(np.argmin(np.abs(grid).sum(axis=1)))
    fits = bool(coarse[zero] >= coarse.max() - p.search_margin)
    picked = _spread(np.argsort(-coarse, kind="stable"), grid, p)
    candidates = []
    for g in picked:
        T_init = motions[g] @ T_world_camera
        r = registration.register(target, source, T_init, p.radius_max_m, 2 * p.max_iterations)
        D = r.T_world_camera @ np.linalg.inv(T_world_camera)
        pose = se2.compose(se2.from_matrix(D), base_pose)
        if not _within(pose, base_pose, p):  # run off the searched window: not a place searched
            continue
        candidates.append(Candidate(pose, _score(surfaces, above, se2.to_matrix(se2.from_matrix(D)), p.search_inlier_m),
                                    float(coarse[g]), grid[g].copy()))
    ms = (time.perf_counter() - t0) * 1e3
    if not candidates:
        return SearchResult(False, None, None, len(grid), 0, ms, "every registration ran off the window", fits)
    candidates.sort(key=lambda c: -c.score)
    best = candidates[0]
    runner_up = next((c for c in candidates[1:] if _distinct(c.pose, best.pose, p)), None)
    if best.score < p.search_min_score:
        return SearchResult(False, best, runner_up, len(grid), len(candidates), ms,
                            f"{LOW_FIT} {best.score:.2f} < {p.search_min_score:g}", fits)
    if runner_up is not None and runner_up.score > best.score - p.search_margin:
        good = [c.pose for c in candidates if c.score > best.score - p.search_margin]
        corridor = _on_one_line([*good, base_pose], p)
        return SearchResult(False, best, runner_up, len(grid), len(candidates), ms,
                            f"not unique: {best.score:.2f} and {runner_up.score:.2f} "
                            f"{np.hypot(*(runner_up.pose[:2] - best.pose[:2])):.2f} m apart", fits or corridor,
                            corridor)
    return SearchResult(True, best, runner_up, len(grid), len(candidates), ms, "", fits)


def _on_one_line(poses: list[np.ndarray], p: LocalizationParams) -> bool:
    """Whether the poses (x, y, yaw) share a heading (within `search_distinct_rad` of the first) and lie on one line
    (within `search_distinct_m` of their principal axis): fits along a corridor, told apart only along it."""
    P = np.asarray(poses, float)
    if np.max(np.abs(wrap_angle(P[:, 2] - P[0, 2]))) > p.search_distinct_rad:
        return False
    xy = P[:, :2] - P[:, :2].mean(axis=0)
    axis = np.linalg.svd(xy, full_matrices=False)[2][0]
    across = xy @ np.array([-axis[1], axis[0]])
    return bool(np.max(np.abs(across)) <= p.search_distinct_m)


def _motion(base_pose: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """The world-frame motion (4×4) that takes the base from `base_pose` to `base_pose` ⊕ offset."""
    return se2.to_matrix(se2.compose(se2.compose(base_pose, offset), se2.inverse(base_pose)))


def _score(surfaces: registration.Target, points_world: np.ndarray, D: np.ndarray, within_m: float) -> float:
    """The share of the points, moved by D (4×4), within `within_m` of a surface."""
    _, d = surfaces.nearest(points_world @ D[:3, :3].T + D[:3, 3])
    return float(np.mean(d <= within_m))


def _spread(order: np.ndarray, grid: np.ndarray, p: LocalizationParams) -> list[int]:
    """The first `search_refined` guesses of `order`, none a grid neighbour of one taken before it."""
    taken: list[int] = []
    for g in order:
        near = any(np.all(np.abs(grid[g, :2] - grid[k, :2]) <= p.search_step_m + 1e-9)
                   and abs(grid[g, 2] - grid[k, 2]) <= p.search_yaw_step_rad + 1e-9 for k in taken)
        if not near:
            taken.append(int(g))
            if len(taken) == p.search_refined:
                break
    return taken


def _within(pose: np.ndarray, base_pose: np.ndarray, p: LocalizationParams) -> bool:
    """Whether `pose` lies inside the searched window around `base_pose` (one grid step of slack)."""
    d = se2.compose(se2.inverse(base_pose), pose)
    return bool(np.all(np.abs(d[:2]) <= p.search_xy_m + p.search_step_m)
                and abs(d[2]) <= p.search_yaw_rad + p.search_yaw_step_rad)


def _distinct(a: np.ndarray, b: np.ndarray, p: LocalizationParams) -> bool:
    return bool(np.hypot(a[0] - b[0], a[1] - b[1]) > p.search_distinct_m
                or abs(wrap_angle(float(a[2] - b[2]))) > p.search_distinct_rad)
