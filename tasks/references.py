"""Build HTMPC references (`core.types.References`) for the active subtask over the horizon.

Base subtasks: the base reference advances along the planned path at `nominal_speed_mps`, heading
along the path, turning to the goal yaw near the end; the arm holds its ready pose (joints, `ReadyHand`), turned
at the shoulder so the hand camera faces the path point `lookahead_m` ahead: the 'ee' of the subtask's order
becomes 'posture'. (A hand pose held in the world on the reference base made the arm reach for where the base
should be, and a hand pose in any frame let the arm switch configurations: over laps it flipped its elbow and
wrist and wound its joints into their limits.)
EE subtasks: the EE reference is the (constant) target pose; the (lower-priority) base reference is a
stance from which the target is within comfortable reach: on the line from the target to where the
base was when the subtask began, at the ready pose's reach, facing the target. Holding the start pose
instead pulled the arm straight (singular) whenever the target was at the edge of its reach.
"""

from __future__ import annotations

import numpy as np

from core.params import SequencerParams
from core.types import BaseReference, EEReference, References
from tasks.ready_hand import ReadyHand


def path_arclength(path: np.ndarray) -> np.ndarray:
    """Cumulative arc length (m) at each vertex of a P×2 path."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])


def project_on_path(path: np.ndarray, s: np.ndarray, xy: np.ndarray, s_min: float = 0.0) -> float:
    """Arc length of the path point nearest to xy, not behind `s_min` (progress never goes back)."""
    if len(path) == 1:
        return 0.0
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", xy - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    proj = a + t[:, None] * ab
    d = np.linalg.norm(proj - xy, axis=1)
    cand = s[:-1] + t * np.diff(s)
    d = np.where(cand + 1e-9 >= s_min - 0.5, d, np.inf)  # allow small back-steps, never large ones
    k = int(np.argmin(d))
    return float(cand[k])


def point_at(path: np.ndarray, s: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Points (K×2) at arc lengths `at` (clamped to the path)."""
    at = np.clip(at, 0.0, s[-1])
    return np.stack([np.interp(at, s, path[:, 0]), np.interp(at, s, path[:, 1])], axis=-1)


def heading_at(path: np.ndarray, s: np.ndarray, at: np.ndarray, eps: float = 0.15) -> np.ndarray:
    """Path tangent heading (rad) at arc lengths `at`."""
    if s[-1] < 1e-6:
        return np.zeros_like(at)
    ahead = point_at(path, s, np.minimum(at + eps, s[-1]))
    behind = point_at(path, s, np.maximum(at - eps, 0.0))
    d = ahead - behind
    return np.arctan2(d[:, 1], d[:, 0])


def unwrap_near(angles: np.ndarray, reference: float) -> np.ndarray:
    """Angles shifted by multiples of 2π to lie within π of the previous one, starting near `reference`."""
    out = np.empty_like(angles)
    prev = reference
    for i, a in enumerate(angles):
        prev = prev + (a - prev + np.pi) % (2 * np.pi) - np.pi
        out[i] = prev
    return out


def navigation_references(path: np.ndarray, s_now: float, yaw_now: float, goal_yaw: float | None,
                          ready: ReadyHand, params: SequencerParams, n_nodes: int, dt: float,
                          order: tuple[str, ...], switched: bool,
                          ee_hold: tuple[np.ndarray, np.ndarray | None] | None = None) -> References:
    """References for a base subtask along `path` from arc length `s_now`; the arm holds its ready pose turned at
    the shoulder toward the path point `lookahead_m` ahead (`ReadyHand`); `ee_hold` (position, rotation or None,
    in the base frame) holds the hand there instead."""
    s = path_arclength(path)
    at = s_now + params.nominal_speed_mps * dt * np.arange(n_nodes + 1)
    xy = point_at(path, s, at)
    yaw = heading_at(path, s, at)
    remaining = s[-1] - at
    if goal_yaw is not None:
        yaw = np.where(remaining < params.goal_slowdown_m, goal_yaw, yaw)
    elif s[-1] < params.goal_slowdown_m:
        yaw = np.full_like(at, yaw_now)
    yaw = unwrap_near(yaw, yaw_now)
    base = BaseReference(xy=xy, yaw=yaw)
    if ee_hold is not None:
        position, rotation = ee_hold
        rot = None if rotation is None else np.asarray(rotation, float)[None]
        return References(order=order, base=base, ee=EEReference(np.asarray(position, float)[None], rot, "base"),
                          switched=switched)
    c, sn = np.cos(yaw), np.sin(yaw)
    look = point_at(path, s, at + params.lookahead_m)
    heading = np.stack([c, sn], axis=-1)
    look = np.where((s[-1] - at < params.lookahead_m)[:, None], xy + params.lookahead_m * heading, look)
    d = look - xy  # the look-ahead point in each node's reference base frame
    look_b = np.column_stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1]])
    limit = np.radians(params.lookahead_turn_max_deg)
    posture = ready.joints(np.clip(ready.bearing_to(look_b), -limit, limit))
    return References(order=tuple("posture" if n == "ee" else n for n in order), base=base, switched=switched,
                      posture=posture)


def manipulation_stance(target: np.ndarray, base_start: np.ndarray, reach_m: float) -> np.ndarray:
    """Base pose (x, y, yaw) `reach_m` from the target's floor projection, toward the start, facing it."""
    d = np.asarray(target[:2], float) - base_start[:2]
    dist = float(np.linalg.norm(d))
    if dist < 1e-6:
        return base_start.copy()
    u = d / dist
    xy = target[:2] - reach_m * u if dist > reach_m else base_start[:2]
    yaw = float(np.arctan2(u[1], u[0]))
    yaw = base_start[2] + (yaw - base_start[2] + np.pi) % (2 * np.pi) - np.pi
    return np.array([xy[0], xy[1], yaw])


def manipulation_references(position: np.ndarray, rotation: np.ndarray | None, stance: np.ndarray,
                            order: tuple[str, ...], switched: bool, frame: str = "world") -> References:
    """References for an EE subtask: a constant EE target (in `frame`) and a base stance (`manipulation_stance`,
    or where the base stands for a base-frame target)."""
    base = BaseReference(xy=np.asarray(stance[:2], float)[None], yaw=np.array([stance[2]]))
    rot = None if rotation is None else np.asarray(rotation, float)[None]
    return References(order=order, base=base, ee=EEReference(np.asarray(position, float)[None], rot, frame),
                      switched=switched)
