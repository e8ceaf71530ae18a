"""Check a sequence's targets when they are authored, against the robot and the boxes of the scene.

One function, `check_sequence`, serves the studio, YAML files, the bridge API and `app run`:

- **base clearance**: a base goal or waypoint keeps the planner's clearance from every box footprint
  (`SequencerParams.inflation_m`, 0.8 m: the base's half length 0.48 m + delta_safe 0.25 m and a grid
  cell; A* would move a goal closer than that);
- **hand clearance**: an EE target keeps the hand's spheres (wrist 0.2 m, tool 0.15 m, rigid in the EE
  frame) delta_safe from every box, and above the floor;
- **a path**: with the robot's start known, every base goal and waypoint is reachable from the one before
  (from the start for the first) on the planner's grid (`tasks/reachability.py`): a goal in a closed pen of
  boxes is refused, with the nearest reachable position;
- **reach**: an EE target is within the arm's reach (shoulder to EE, less `reach_margin_m`) from some
  base pose that keeps the base clearance; a base-frame target within reach of the shoulder and clear of
  the robot's own base.

An anchored target (`tasks/anchors.py`) is checked where it is on its object now (`anchors`: name → the
box it names, its current extent and pose), with the same rules; one whose object is not known yet is a
warning (it is checked again when the object is seen, and whenever it moves: app/target_check.py).

A target that breaks a rule is refused with the reason and the nearest acceptable value. Rules that
depend on where the boxes are become warnings when the operator says the scene will change before the
subtask runs (`scene_may_change`): the operator decides. Boxes are plain geometry (anything with
`id`, centre `position`, full `size` and `yaw`), so scene boxes and mapped objects both serve.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from functools import lru_cache
from typing import Protocol

import numpy as np

from core.params import SequencerParams
from core.robot.collision_boxes import base_boxes
from core.robot.model import RobotModel
from core.yaml_validation import FileFormatError, line_of
from tasks.anchors import MapObjects, ObjectView, resolve_pose
from tasks.reachability import FreeSpace
from tasks.schema import BasePose, BaseSubtask, EEPose, EESubtask, TaskSequence

HAND_SPHERES = ("wrist_3", "tool")
"""Spheres rigid in the EE frame (the wrist_2 sphere turns with the last joint about the tool axis)."""
REACH_MARGIN_M = 0.1
"""The arm's reach is taken this much short of full stretch, where the arm is singular."""
ACCEPT_MARGIN_M = 0.01
"""A suggested value clears each rule by this much (it survives rounding to centimetres)."""


class BoxLike(Protocol):
    """A box as plain geometry, read-only: a scene `Box` or an `Obstacle`."""

    @property
    def id(self) -> str: ...
    @property
    def position(self) -> tuple[float, float, float]: ...
    @property
    def size(self) -> tuple[float, float, float]: ...
    @property
    def yaw(self) -> float: ...


@dataclass(frozen=True)
class Obstacle:
    """A box as plain geometry: centre `position` (m), full `size` (m), `yaw` (rad)."""

    id: str
    position: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0


class Rule(StrEnum):
    BASE_CLEARANCE = "base_clearance"
    HAND_CLEARANCE = "hand_clearance"
    FLOOR = "floor"
    REACH = "reach"
    BASE_POSE = "base_pose"
    SELF_COLLISION = "self_collision"
    PATH = "path"
    """No base path reaches the goal from the robot's start (boxes close it in)."""
    ANCHOR = "anchor"


SCENE_RULES = frozenset({Rule.BASE_CLEARANCE, Rule.HAND_CLEARANCE, Rule.BASE_POSE, Rule.PATH, Rule.ANCHOR})
"""Rules that depend on where the boxes are now."""


class Severity(StrEnum):
    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True)
class TargetFinding:
    """One broken rule: which subtask and field, why, and the nearest acceptable value (None if none found)."""

    index: int
    field: str
    rule: Rule
    severity: Severity
    message: str
    nearest: tuple[float, ...] | None = None

    def __str__(self) -> str:
        near = "" if self.nearest is None else f"; nearest acceptable: ({', '.join(f'{v:.2f}' for v in self.nearest)})"
        what = "refused" if self.severity == Severity.ERROR else "warning"
        return f"subtask {self.index + 1} ({what}): {self.message}{near}"


class TargetError(FileFormatError):
    """A sequence whose targets break a rule; `findings` holds every one (`problems` their field and line)."""

    def __init__(self, source: str, findings: list[TargetFinding], text: str | None = None) -> None:
        self.findings = findings
        problems = [(f.field, line_of(text, f.field) if text else None, str(f)) for f in findings]
        super().__init__(source, problems)


# --- geometry ------------------------------------------------------------------------------------------

def _local(box: BoxLike, p: np.ndarray) -> np.ndarray:
    """Points (…, D) in the box's frame (D = 2: the footprint, 3: the box)."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    d = np.asarray(p, float) - np.asarray(box.position, float)[: p.shape[-1]]
    out = d.copy()
    out[..., 0] = c * d[..., 0] + s * d[..., 1]
    out[..., 1] = -s * d[..., 0] + c * d[..., 1]
    return out


def box_distance(box: BoxLike, p: np.ndarray) -> np.ndarray:
    """Signed distance (m) from points p (…, 3) to the box (negative inside); with p (…, 2), to its footprint."""
    p = np.asarray(p, float)
    q = np.abs(_local(box, p)) - 0.5 * np.asarray(box.size, float)[: p.shape[-1]]
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    return outside + np.minimum(q.max(axis=-1), 0.0)


def _clearance(boxes: Sequence[BoxLike], p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance to the nearest box and its index, for points p (…, D); +inf with no boxes."""
    if not boxes:
        return np.full(p.shape[:-1], np.inf), np.zeros(p.shape[:-1], int)
    d = np.stack([box_distance(b, p) for b in boxes])
    return d.min(axis=0), d.argmin(axis=0)


def _fibonacci_sphere(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def nearest_acceptable(p: np.ndarray, violation, max_radius_m: float = 3.0, step_m: float = 0.01) -> np.ndarray | None:
    """The point nearest to p where `violation(points) <= 0` (a vectorised function of (K, D) points).

    Newton steps on the violation (exact for one box) give one candidate; rings of growing radius around p
    (2D: every 2°, 3D: 400 directions) give the nearest one among several boxes. None if neither finds one.
    """
    p = np.asarray(p, float)
    cands = []
    x = p.copy()
    eps = 1e-4
    for _ in range(40):
        v = float(violation(x[None])[0])
        if v <= 0.0:
            cands.append(x)
            break
        grad = np.array([(violation((x + eps * e)[None])[0] - violation((x - eps * e)[None])[0]) / (2 * eps)
                         for e in np.eye(len(x))])
        if not np.all(np.isfinite(grad)) or grad @ grad < 1e-12:
            break
        x = x - (v + 1e-4) * grad / (grad @ grad)
    if len(p) == 2:
        a = np.radians(np.arange(0.0, 360.0, 2.0))
        dirs = np.column_stack([np.cos(a), np.sin(a)])
    else:
        dirs = _fibonacci_sphere(400)
    for r in np.arange(step_m, max_radius_m + step_m, step_m):
        if cands and r > np.linalg.norm(cands[0] - p):
            break
        pts = p + r * dirs
        ok = violation(pts) <= 0.0
        if ok.any():
            cands.append(pts[np.argmax(ok)])
            break
    return min(cands, key=lambda c: float(np.linalg.norm(c - p))) if cands else None


# --- the robot's numbers ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class RobotEnvelope:
    """What the checks need to know of the robot, from its model and the controller's delta_safe."""

    delta_safe_m: float
    base_clearance_m: float
    """How far the base centre keeps from box footprints: the planner's obstacle inflation."""
    base_top_m: float
    """Boxes whose bottom is above this (the top of the base's rack + delta_safe) do not block the base."""
    base_body: tuple[tuple[np.ndarray, np.ndarray], ...]
    """The base's collision boxes (body, rack) in the base frame: lower and upper corner."""
    hand: tuple[tuple[str, np.ndarray, float], ...]
    """Hand spheres rigid in the EE frame: name, centre in the EE frame, radius."""
    shoulder_m: np.ndarray
    """The shoulder (UR10 shoulder_link origin) in the base frame."""
    reach_m: float
    """Shoulder to EE, full stretch less the margin."""
    wrist_reach_m: float
    """Shoulder to the wrist_3 sphere centre, full stretch less the margin (for targets with an orientation)."""

    @classmethod
    def of(cls, robot: RobotModel, delta_safe_m: float, reach_margin_m: float = REACH_MARGIN_M,
           base_clearance_m: float = SequencerParams().inflation_m) -> RobotEnvelope:
        shoulder, reach, wrist_reach = _arm_reach(robot)
        q0 = np.zeros(robot.nq)
        q0[3:] = [0.0, -1.6, 2.2, -0.2, math.pi / 2, math.pi]
        T_ee = robot.ee_pose(q0)
        centres = robot.sphere_centres(q0)
        names = [s.name for s in robot.spheres]
        radii = {s.name: s.radius_m for s in robot.spheres}
        in_ee = {n: (np.linalg.inv(T_ee) @ np.r_[c, 1.0])[:3] for n, c in zip(names, centres, strict=True)}
        body = tuple((b.lo, b.hi) for b in base_boxes(robot.params))
        return cls(delta_safe_m=delta_safe_m, base_clearance_m=base_clearance_m,
                   base_top_m=max(hi[2] for _, hi in body) + delta_safe_m, base_body=body,
                   hand=tuple((n, in_ee[n], radii[n]) for n in HAND_SPHERES), shoulder_m=shoulder,
                   reach_m=reach - reach_margin_m, wrist_reach_m=wrist_reach - reach_margin_m)

    @property
    def wrist_in_ee(self) -> np.ndarray:
        return next(c for n, c, _ in self.hand if n == "wrist_3")


@lru_cache(maxsize=8)
def _arm_reach(robot: RobotModel, samples: int = 1500) -> tuple[np.ndarray, float, float]:
    """Shoulder position in the base frame, and the largest shoulder–EE and shoulder–wrist distances over
    arm configurations within limits (a fixed sample: deterministic)."""
    rng = np.random.default_rng(0)
    best_ee = best_wrist = 0.0
    shoulder = np.zeros(3)
    for _ in range(samples):
        q = robot.random_q(rng)
        q[:3] = 0.0
        poses = robot.frame_poses(q, ("shoulder_link", "ee", "sphere_wrist_3"))
        shoulder = poses["shoulder_link"][:3, 3]
        best_ee = max(best_ee, float(np.linalg.norm(poses["ee"][:3, 3] - shoulder)))
        best_wrist = max(best_wrist, float(np.linalg.norm(poses["sphere_wrist_3"][:3, 3] - shoulder)))
    return shoulder.copy(), best_ee, best_wrist


# --- the rules -------------------------------------------------------------------------------------------

def _base_boxes(boxes: Sequence[BoxLike], env: RobotEnvelope) -> list[BoxLike]:
    return [b for b in boxes if b.position[2] - 0.5 * b.size[2] < env.base_top_m]


def _base_violation(boxes: Sequence[BoxLike], env: RobotEnvelope):
    blocking = _base_boxes(boxes, env)
    return lambda xy: env.base_clearance_m + ACCEPT_MARGIN_M - _clearance(blocking, np.asarray(xy, float))[0]


def _fmt(v: Iterable[float]) -> str:
    return "(" + ", ".join(f"{x:.2f}" for x in v) + ")"


def _rounded(p: np.ndarray | None) -> tuple[float, ...] | None:
    return None if p is None else tuple(round(float(x), 2) for x in p)


def check_base_pose(xy: np.ndarray, boxes: Sequence[BoxLike], env: RobotEnvelope, what: str = "base goal",
                    ) -> tuple[str, tuple[float, ...] | None] | None:
    """None if the base at xy keeps its clearance from every box; else (reason, nearest acceptable xy)."""
    blocking = _base_boxes(boxes, env)
    xy = np.asarray(xy, float)
    d, k = _clearance(blocking, xy[None])
    if d[0] >= env.base_clearance_m:
        return None
    box = blocking[int(k[0])]
    where = "inside" if d[0] < 0 else f"{d[0]:.2f} m from"
    reason = (f"{what} {_fmt(xy)} is {where} {box.id}; the base keeps {env.base_clearance_m:.2f} m from boxes "
              f"(the planner's clearance: the base's half length, delta_safe {env.delta_safe_m:.2f} m and a grid cell)")
    return reason, _rounded(nearest_acceptable(xy, _base_violation(boxes, env)))


def _hand_points(p: np.ndarray, R: np.ndarray | None, env: RobotEnvelope) -> list[tuple[str, np.ndarray, float]]:
    """Hand spheres at EE position p (…, 3): (label, centre, radius), exact with an orientation R; without one,
    the EE point stands for them with the radius no orientation can avoid (a sphere's radius less its offset)."""
    if R is not None:
        return [(f"{n} sphere", p + R @ c, r) for n, c, r in env.hand]
    n, c, r = max(env.hand, key=lambda h: h[2] - np.linalg.norm(h[1]))
    return [(f"{n} sphere ({r:.2f} m, {np.linalg.norm(c):.2f} m from the EE)", p, r - float(np.linalg.norm(c)))]


def _hand_violation(boxes: Sequence[BoxLike], R: np.ndarray | None, env: RobotEnvelope):
    def violation(p: np.ndarray) -> np.ndarray:
        worst = np.full(len(p), -np.inf)
        for _, c, r in _hand_points(np.asarray(p, float), R, env):
            need = r + env.delta_safe_m + ACCEPT_MARGIN_M
            worst = np.maximum(worst, need - _clearance(boxes, c)[0])
            worst = np.maximum(worst, r + ACCEPT_MARGIN_M - c[..., 2])  # and above the floor
        return worst
    return violation


def _reach_point(p: np.ndarray, R: np.ndarray | None, env: RobotEnvelope) -> tuple[np.ndarray, float]:
    """The point whose distance from the shoulder limits reach (the wrist with an orientation, else the EE)."""
    return (p + R @ env.wrist_in_ee, env.wrist_reach_m) if R is not None else (p.copy(), env.reach_m)


def _free_bases(centre_xy: np.ndarray, radius: float, boxes: Sequence[BoxLike], env: RobotEnvelope,
                spacing_m: float = 0.05) -> np.ndarray:
    """Base positions (K×2) within `radius` of centre_xy that keep the base clearance."""
    n = int(math.ceil(radius / spacing_m))
    g = np.arange(-n, n + 1) * spacing_m
    X, Y = np.meshgrid(g, g, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    pts = centre_xy + pts[np.linalg.norm(pts, axis=1) <= radius]
    return pts[_base_violation(boxes, env)(pts) <= 0.0]


def _horizontal_reach(w: np.ndarray, reach: float, env: RobotEnvelope) -> float:
    """How far (m) the base centre may be from the reach point's floor projection: the shoulder's horizontal
    reach at that height plus the shoulder's offset ahead of the base centre (the base faces the target)."""
    dz = w[2] - env.shoulder_m[2]
    return math.sqrt(max(reach**2 - dz**2, 0.0)) + float(np.hypot(*env.shoulder_m[:2]))


def _floor_findings(p: np.ndarray, R: np.ndarray | None, env: RobotEnvelope) -> list[tuple[Rule, str]]:
    """The hand's spheres stay above the floor (the map has no floor: the controller would not keep them off it)."""
    for name, c, r in _hand_points(p, R, env):
        if c[2] < r:
            return [(Rule.FLOOR, f"the hand's {name} would reach {r - c[2]:.2f} m into the floor")]
    return []


def _world_ee_findings(pose: EEPose, boxes: Sequence[BoxLike], env: RobotEnvelope) -> list[tuple[Rule, str]]:
    p = np.asarray(pose.position, float)
    R = pose.rotation()
    out = _floor_findings(p, R, env)
    w, reach = _reach_point(p, R, env)
    dz = w[2] - env.shoulder_m[2]
    if abs(dz) > reach:
        out.append((Rule.REACH, f"the {'wrist' if R is not None else 'hand'} would be {abs(dz):.2f} m "
                    f"{'above' if dz > 0 else 'below'} the shoulder (height {env.shoulder_m[2]:.2f} m); the arm "
                    f"reaches {reach:.2f} m"))
        return out
    gaps = []
    for name, c, r in _hand_points(p, R, env):
        d, k = _clearance(boxes, c[None])
        gaps.append((float(d[0]) - r - env.delta_safe_m, name, float(d[0]), r, int(k[0])))
    gap, name, d, r, k = min(gaps)
    if gap < 0:
        out.append((Rule.HAND_CLEARANCE, f"the hand's {name} would be {'inside' if d < 0 else f'{d:.2f} m from'} "
                    f"{boxes[k].id}; it keeps {r + env.delta_safe_m:.2f} m ({r:.2f} m + delta_safe "
                    f"{env.delta_safe_m:.2f} m)"))
    radius = _horizontal_reach(w, reach, env)
    if not len(_free_bases(w[:2], radius, boxes, env)):
        out.append((Rule.BASE_POSE, f"no base pose that keeps {env.base_clearance_m:.2f} m from the boxes has the "
                    f"target within the arm's reach ({reach:.2f} m from the shoulder)"))
    return out


def _fix_world_ee(pose: EEPose, boxes: Sequence[BoxLike], env: RobotEnvelope) -> np.ndarray | None:
    """The nearest EE position (same orientation) that passes every rule, found rule by rule; None if the
    fixes do not settle."""
    p = np.asarray(pose.position, float)
    R = pose.rotation()
    for _ in range(4):
        w, reach = _reach_point(p, R, env)
        dz = w[2] - env.shoulder_m[2]
        if abs(dz) > reach - ACCEPT_MARGIN_M:
            p = p - (dz - math.copysign(reach - ACCEPT_MARGIN_M, dz)) * np.array([0.0, 0.0, 1.0])
        fixed = nearest_acceptable(p, _hand_violation(boxes, R, env), max_radius_m=2.0)
        if fixed is None:
            return None
        p = fixed
        w, reach = _reach_point(p, R, env)
        radius = _horizontal_reach(w, reach, env) - ACCEPT_MARGIN_M
        if not len(_free_bases(w[:2], radius, boxes, env)):
            bases = _free_bases(w[:2], radius + 4.0, boxes, env)
            if not len(bases):
                return None
            b = bases[np.argmin(np.linalg.norm(bases - w[:2], axis=1))]
            d = w[:2] - b
            p = p - np.r_[d - d / np.linalg.norm(d) * (radius - 0.05), 0.0]
        candidate = EEPose(position=tuple(np.round(p, 2)), rpy_deg=pose.rpy_deg)
        if not _world_ee_findings(candidate, boxes, env):
            return np.round(p, 2)
    return None


def _base_frame_findings(pose: EEPose, env: RobotEnvelope) -> list[tuple[Rule, str]]:
    p = np.asarray(pose.position, float)
    R = pose.rotation()
    out = _floor_findings(p, R, env)
    w, reach = _reach_point(p, R, env)
    dist = float(np.linalg.norm(w - env.shoulder_m))
    if dist > reach:
        out.append((Rule.REACH, f"the {'wrist' if R is not None else 'hand'} would be {dist:.2f} m from the "
                    f"shoulder; the arm reaches {reach:.2f} m"))
    for name, c, r in _hand_points(p, R, env):
        gaps = [float(_box_gap(c, lo, hi)) - r for lo, hi in env.base_body]
        if min(gaps) < 0:
            out.append((Rule.SELF_COLLISION, f"the hand's {name} would be {-min(gaps):.2f} m inside the "
                        "robot's own base"))
            break
    return out


def _box_gap(c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Distance from points c (…, 3) to an axis-aligned box [lo, hi] (0 inside)."""
    return np.linalg.norm(np.maximum(np.maximum(lo - c, c - hi), 0.0), axis=-1)


def _self_violation(R: np.ndarray | None, env: RobotEnvelope):
    def violation(p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        worst = np.full(len(p), -np.inf)
        for _, c, r in _hand_points(p, R, env):
            worst = np.maximum(worst, r + ACCEPT_MARGIN_M - c[..., 2])
            for lo, hi in env.base_body:
                worst = np.maximum(worst, r + ACCEPT_MARGIN_M - _box_gap(c, lo, hi))
        w, reach = _reach_point(p, R, env)
        return np.maximum(worst, np.linalg.norm(w - env.shoulder_m, axis=-1) - reach + ACCEPT_MARGIN_M)
    return violation


def _finding(index: int, field: str, rule: Rule, message: str, nearest, scene_may_change: bool) -> TargetFinding:
    severity = Severity.WARNING if scene_may_change and rule in SCENE_RULES else Severity.ERROR
    if severity == Severity.WARNING:
        message += " (accepted: the scene may change before this subtask runs)"
    return TargetFinding(index, field, rule, severity, message, nearest)


def _path_findings(sequence: TaskSequence, boxes: Sequence[BoxLike], env: RobotEnvelope, start_xy: np.ndarray,
                   planner: SequencerParams, wanted: set[int] | None, scene_may_change: bool,
                   anchors: Mapping[str, BoxLike] | None = None) -> list[TargetFinding]:
    """Base goals and waypoints that no path reaches from the one before (the first from `start_xy`)."""
    blocking = _base_boxes(boxes, env)
    if not blocking:
        return []
    space = FreeSpace.of(lambda xy: _clearance(blocking, xy)[0], env.base_clearance_m, planner.plan_bounds_m,
                         planner.grid_cell_m)
    out: list[TargetFinding] = []
    here = np.asarray(start_xy, float)[:2]
    for i, sub in enumerate(sequence.subtasks):
        if not isinstance(sub, BaseSubtask):
            continue
        poses = [(f"subtasks.{i}.waypoints.{k}", "base waypoint", w) for k, w in enumerate(sub.waypoints)]
        if sub.target is not None:
            poses.append((f"subtasks.{i}.target", "base goal", sub.target))
        for field, what, authored in poses:
            pose = _placed(authored, anchors or {})
            if not isinstance(pose, BasePose):
                continue  # an anchored goal whose object is not in the map yet: checked once it is seen
            xy = pose.xy()
            if space.reachable(here, xy):
                here = xy
                continue  # an unreachable one is never reached: the next leg starts where the base is
            if wanted is None or i in wanted:
                box = blocking[int(_clearance(blocking, xy[None])[1][0])]
                message = (f"{what} {_fmt(xy)}: no path reaches it from {_fmt(here)}; the boxes around it "
                           f"(nearest {box.id}) close it in for the base")
                out.append(_finding(i, field, Rule.PATH, message, _rounded(space.nearest_reachable(here, xy)),
                                    scene_may_change))
    return out


def _placed(pose: BasePose | EEPose, anchors: Mapping[str, BoxLike]) -> BasePose | EEPose | None:
    """The pose where its anchor puts it on its object now (unchanged if not anchored), None if not known."""
    if pose.anchor is None:
        return pose
    box = anchors.get(pose.anchor.object)
    if box is None:
        return None
    obj = ObjectView(box.id, pose.anchor.object, np.asarray(box.position, float), float(box.yaw),
                     np.asarray(box.size, float))
    placed = resolve_pose(pose, MapObjects(0.0, (obj,)))
    return None if isinstance(placed, str) else placed


def _findings_for(sub: BaseSubtask | EESubtask, index: int, boxes: Sequence[BoxLike], env: RobotEnvelope,
                  scene_may_change: bool, anchors: Mapping[str, BoxLike] | None = None) -> list[TargetFinding]:
    out: list[TargetFinding] = []

    def add(field: str, rule: Rule, message: str, nearest) -> None:
        out.append(_finding(index, field, rule, message, nearest, scene_may_change))

    poses: list[tuple[str, BasePose | EEPose]] = [(f"subtasks.{index}.waypoints.{k}", w)
                                                  for k, w in enumerate(sub.waypoints)]
    if sub.target is not None:
        poses.append((f"subtasks.{index}.target", sub.target))
    if isinstance(sub, BaseSubtask) and sub.ee is not None:
        poses.append((f"subtasks.{index}.ee", sub.ee))
    for field, authored in poses:
        pose = _placed(authored, anchors or {})
        if pose is None:
            name = authored.anchor.object if authored.anchor is not None else "?"
            out.append(TargetFinding(index, field, Rule.ANCHOR, Severity.WARNING,
                                     f"{name} is not in the map yet: its anchored target is checked when it is seen"))
            continue
        if isinstance(pose, BasePose):
            what = "base waypoint" if ".waypoints." in field else "base goal"
            found = check_base_pose(pose.xy(), boxes, env, what)
            if found is not None:
                add(field, Rule.BASE_CLEARANCE, *found)
        elif pose.frame == "base":
            problems = _base_frame_findings(pose, env)
            if problems:
                fixed = nearest_acceptable(np.asarray(pose.position, float), _self_violation(pose.rotation(), env),
                                           max_radius_m=2.0)
                for rule, message in problems:
                    add(field, rule, f"EE target {_fmt(pose.position)} in the base frame: {message}", _rounded(fixed))
        else:
            problems = _world_ee_findings(pose, boxes, env)
            if problems:
                fixed = _fix_world_ee(pose, boxes, env)
                for rule, message in problems:
                    add(field, rule, f"EE target {_fmt(pose.position)}: {message}", _rounded(fixed))
    return out


def check_sequence(sequence: TaskSequence, boxes: Iterable[BoxLike], envelope: RobotEnvelope, *,
                   scene_may_change: bool = False, indices: Iterable[int] | None = None,
                   start_xy: Sequence[float] | np.ndarray | None = None,
                   planner: SequencerParams | None = None,
                   anchors: Mapping[str, BoxLike] | None = None) -> list[TargetFinding]:
    """Every broken rule of the sequence's targets (of the subtasks in `indices`, default all), in order.

    Errors refuse the sequence; warnings accept it (rules that depend on the boxes, when `scene_may_change`).
    With the robot's `start_xy` (the scene is known), base goals no path reaches are refused too, on the grid
    of `planner` (default `SequencerParams()`). `anchors` places anchored targets: object name → the box it
    names now.
    """
    boxes = list(boxes)
    wanted = None if indices is None else set(indices)
    out: list[TargetFinding] = []
    for i, sub in enumerate(sequence.subtasks):
        if wanted is None or i in wanted:
            out += _findings_for(sub, i, boxes, envelope, scene_may_change, anchors)
    if start_xy is not None:
        blocked = {f.field for f in out if f.rule == Rule.BASE_CLEARANCE}
        out += [f for f in _path_findings(sequence, boxes, envelope, np.asarray(start_xy, float),
                                          planner or SequencerParams(), wanted, scene_may_change, anchors)
                if f.field not in blocked]
        out.sort(key=lambda f: f.index)
    return out


def require_valid(sequence: TaskSequence, boxes: Iterable[BoxLike], envelope: RobotEnvelope, *,
                  scene_may_change: bool = False, indices: Iterable[int] | None = None, source: str = "sequence",
                  text: str | None = None, start_xy: Sequence[float] | np.ndarray | None = None,
                  planner: SequencerParams | None = None,
                  anchors: Mapping[str, BoxLike] | None = None) -> list[TargetFinding]:
    """`check_sequence`, raising `TargetError` (with YAML lines when `text` is given) if any finding is an
    error; returns the warnings."""
    findings = check_sequence(sequence, boxes, envelope, scene_may_change=scene_may_change, indices=indices,
                              start_xy=start_xy, planner=planner, anchors=anchors)
    errors = [f for f in findings if f.severity == Severity.ERROR]
    if errors:
        raise TargetError(source, errors, text)
    return findings


def changed_subtasks(before: TaskSequence, after: TaskSequence) -> list[int]:
    """Indices of subtasks of `after` whose targets are new or differ from `before` (so an edit of a name
    does not re-judge targets the operator already accepted)."""
    old = [(s.kind, s.path(), getattr(s, "ee", None)) for s in before.subtasks]
    return [i for i, s in enumerate(after.subtasks) if (s.kind, s.path(), getattr(s, "ee", None)) not in old]
