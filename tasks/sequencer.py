"""The sequencer: runs a `TaskSequence` subtask by subtask and hands the HTMPC its references.

Each call to `update(state, occupied_points, t)` checks the active subtask (tolerance held for its
dwell time → done; past its timeout → failed, and the sequence stops), re-plans the base path when
the map changed or every `replan_period_s`, and returns the `References` for the controller, or None
when nothing is active (finished, failed or empty): the runtime then stops the robot.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np

from core.angles import wrap_angle
from core.params import HTMPCParams, SequencerParams
from core.robot.model import RobotModel
from core.types import References, RobotState
from tasks.anchors import MapObjects, anchor_of, describe, is_anchored, resolve_subtask, settling
from tasks.occupancy import OccupancyGrid
from tasks.path_planner import NoPathError, plan_path
from tasks.ready_hand import ReadyHand
from tasks.references import (
    manipulation_references,
    manipulation_stance,
    navigation_references,
    path_arclength,
    project_on_path,
)
from tasks.schema import BasePose, BaseSubtask, EESubtask, TaskSequence
from tasks.stance_turn import needs_turn, turn_references

log = logging.getLogger(__name__)


class Outcome(StrEnum):
    PENDING = "pending"
    ACTIVE = "active"
    DONE = "done"
    FAILED = "failed"
    SKIPPED = "skipped"
    """The operator skipped it (e.g. after "no path to the goal"); the sequence goes on with the next one."""


@dataclass(frozen=True)
class GoalShift:
    """The base goal the planner drove to instead of the authored one (blocked on the map): (x, y) each."""

    original: tuple[float, float]
    driven: tuple[float, float]

    @property
    def distance_m(self) -> float:
        return math.hypot(self.driven[0] - self.original[0], self.driven[1] - self.original[1])


@dataclass(frozen=True)
class Blocked:
    """The base made no progress toward its goal for `for_s` (s); the nearest occupied point of the map is
    `obstacle_xy`, `obstacle_m` from the base centre (the UI names the object there)."""

    for_s: float
    obstacle_xy: tuple[float, float] | None
    obstacle_m: float


@dataclass(frozen=True)
class SubtaskProgress:
    """How one subtask is going: errors to its goal (m, deg), time active and time held in tolerance."""

    index: int
    name: str
    kind: str
    outcome: Outcome = Outcome.PENDING
    elapsed_s: float = 0.0
    held_s: float = 0.0
    position_error_m: float = float("nan")
    orientation_error_deg: float = float("nan")
    message: str = ""
    timeout_s: float = float("nan")
    goal_shift: GoalShift | None = None
    """Set while the base drives to a goal the planner moved off an obstacle; completion is judged there."""
    blocked: Blocked | None = None
    """Set while the base makes no progress (`SequencerParams.stall_s`); cleared when it moves on."""
    no_path: bool = False
    """The planner found no path to the goal (or a waypoint) on the current map: the base holds."""
    anchor_object: str | None = None
    """The object the subtask's goal is anchored on (None: a world or base-frame goal)."""
    anchor_label: str = ""
    """Where on it, for the operator: 'top of box_3'."""
    anchored_goal: tuple[float, float, float] | None = None
    """Where an anchored goal is now in the world (the studio joins it to its object); None when not anchored
    or not placed (waiting)."""


def _anchor_object(sub: BaseSubtask | EESubtask) -> str | None:
    anchor = anchor_of(sub)
    return None if anchor is None else anchor.object


def _facing(sub: BaseSubtask | EESubtask, state: RobotState, objects: MapObjects | None) -> float | None:
    """The heading (rad) that faces the base toward where the anchored object of `sub` was last mapped (or
    declared); None (hold the heading) when that is not known or is where the base stands."""
    name = _anchor_object(sub)
    where = None if name is None or objects is None else objects.last_known.get(name)
    if where is None:
        return None
    d = np.asarray(where, float)[:2] - state.q[:2]
    return float(math.atan2(d[1], d[0])) if float(np.hypot(*d)) > 0.05 else None


def _settling_message(message: str) -> bool:
    """Whether a progress message is the settling wait's (`_note_settling`: `tasks.anchors.unsettled` + ': waiting')."""
    return message.endswith("not settled: waiting")


def _angle_between(R_a: np.ndarray, R_b: np.ndarray) -> float:
    cos = (np.trace(R_a.T @ R_b) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))


def _goal_shift(goal: np.ndarray, path_end: np.ndarray) -> GoalShift | None:
    """The planned path ends at the final goal, or at the free cell `plan_path` moved a blocked one to."""
    if float(np.hypot(*(path_end - goal))) < 1e-6:
        return None
    return GoalShift((float(goal[0]), float(goal[1])), (float(path_end[0]), float(path_end[1])))


def plural(n: int, noun: str) -> str:
    """'1 subtask', '2 subtasks'."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def nearest_obstacle_point(occupied: np.ndarray | None, xy: np.ndarray, z_range_m: tuple[float, float],
                           ) -> tuple[tuple[float, float] | None, float]:
    """The occupied point (between the heights `z_range_m`) nearest to xy in the plane, and its distance (m)."""
    if occupied is None or not len(occupied):
        return None, math.nan
    pts = np.asarray(occupied, float).reshape(-1, 3)
    pts = pts[(pts[:, 2] >= z_range_m[0]) & (pts[:, 2] <= z_range_m[1])]
    if not len(pts):
        return None, math.nan
    d = np.hypot(pts[:, 0] - xy[0], pts[:, 1] - xy[1])
    k = int(np.argmin(d))
    return (float(pts[k, 0]), float(pts[k, 1])), float(d[k])


class Sequencer:
    """Owns the progress through one sequence; pure function of the inputs it is given."""

    def __init__(self, robot: RobotModel, sequence: TaskSequence, params: SequencerParams | None = None,
                 n_nodes: int | None = None, dt: float | None = None) -> None:
        """`n_nodes`, `dt` (s): the controller's horizon the references are sampled on (default: `HTMPCParams`)."""
        self.robot = robot
        self.sequence = sequence
        self.params = params or SequencerParams()
        horizon = HTMPCParams()
        self.n_nodes = horizon.N if n_nodes is None else n_nodes
        self.dt = horizon.dt_s if dt is None else dt
        self.margin_growth_m = 0.0
        """What the controller's delta_safe is grown by (the pose's uncertainty, `set_margin_growth`): the planner
        grows its obstacles by the same, so its paths keep the clearance the controller now keeps."""
        self.ready = ReadyHand.of(robot)
        """The hand's ready pose in the base frame: what the arm holds while the base drives."""
        self.ee_offset_base = self.ready.position
        self.reset()

    def set_margin_growth(self, growth_m: float) -> None:
        """Grow the planner's obstacles (`inflation_m`, `inflation_min_m`) by `growth_m` from the next plan on, as
        the controller's delta_safe is grown; a change of half a grid cell or more plans again at once."""
        if not (math.isfinite(growth_m) and growth_m >= 0.0):
            raise ValueError(f"the margin growth must be a finite distance >= 0 m, got {growth_m}")
        if abs(growth_m - self.margin_growth_m) >= self.params.grid_cell_m / 2:
            self._plan_t = -math.inf  # re-plan the base path now
        self.margin_growth_m = float(growth_m)

    def _inflations_m(self) -> tuple[float, float]:
        """The preferred and the least obstacle growth for A* (m), both grown by `margin_growth_m`."""
        p, g = self.params, self.margin_growth_m
        return p.inflation_m + g, min(p.inflation_min_m, p.inflation_m) + g

    def reset(self) -> None:
        """Back to the first subtask, nothing done."""
        self.index = 0
        self.progress = [SubtaskProgress(i, s.name or describe(s) or f"{s.kind} {i + 1}", s.kind,
                                         timeout_s=s.timeout_s, anchor_object=_anchor_object(s),
                                         anchor_label=describe(s))
                         for i, s in enumerate(self.sequence.subtasks)]
        self._started_t: float | None = None
        self._held_since: float | None = None
        self._settle_told = False
        self._unsettled_since: float | None = None
        """When the active subtask was first held at its goal on an unsettled object (`anchor_base_settle_s`)."""
        self._switched = True
        self.path: np.ndarray | None = None
        self._s_progress = 0.0
        self._plan_t = -math.inf
        self._grid_sig: int | None = None
        self._hold_base = np.zeros(3)
        """Where the base holds during an EE subtask (set when the subtask begins)."""
        self._ee_waypoint = 0
        self._base_waypoint = 0
        self._paused_at: float | None = None
        self._resume_pending = False
        self._best_error = math.inf
        """The base's least error to its goal so far, and when it last fell by `stall_progress_m` (s)."""
        self._improved_t = 0.0
        self._anchor_goal: np.ndarray | None = None
        """Where the anchored goal was when the plan was made (a move beyond `anchor_follow_m` re-plans)."""
        self._turning: bool | None = None
        """EE subtask: the base is turning into its stance first (`tasks/stance_turn.py`); None: not decided yet."""
        self.notices: list[str] = []
        """Messages for the operator since the last `take_notices` (an anchored target follows its object)."""

    def pause(self, t: float) -> None:
        """Stop the subtask clock at time t: paused time counts toward neither `timeout_s` nor `dwell_s`."""
        self._resume_pending = False  # paused again before a resume took effect: still paused since then
        if self._paused_at is None:
            self._paused_at = t

    def resume(self, t: float | None = None) -> None:
        """Run the subtask clock again from time t (the paused span moves the subtask's start forward); with no
        t, from the time of the next `update`: a robot's clock read at Start may still be the one from before
        the pause (a driver that went silent), and only its next state says how long the pause lasted."""
        if self._paused_at is None:
            return
        if t is None:
            self._resume_pending = True
            return
        self._resume_pending = False
        span = max(0.0, t - self._paused_at)
        self._paused_at = None
        if self._started_t is not None:
            self._started_t += span
        if self._held_since is not None:
            self._held_since += span
        self._improved_t += span

    @property
    def finished(self) -> bool:
        return bool(self.progress) and all(p.outcome in (Outcome.DONE, Outcome.SKIPPED) for p in self.progress)

    @property
    def failed(self) -> bool:
        return any(p.outcome == Outcome.FAILED for p in self.progress)

    @property
    def active(self) -> BaseSubtask | EESubtask | None:
        if self.failed or self.index >= len(self.sequence.subtasks):
            return None
        return self.sequence.subtasks[self.index]

    def status_line(self) -> str:
        """One line for the operator: the active subtask and how it is going, or the outcome."""
        if not self.sequence.subtasks:
            return "no subtasks"
        if self.failed:
            p = next(p for p in self.progress if p.outcome == Outcome.FAILED)
            return f"failed: {p.name}: {p.message}"
        if self.finished:
            skipped = sum(p.outcome == Outcome.SKIPPED for p in self.progress)
            return f"sequence finished ({plural(len(self.progress), 'subtask')}" + (
                f", {skipped} skipped)" if skipped else ")")
        p = self.progress[self.index]
        if p.outcome == Outcome.PENDING:
            return f"ready: {plural(len(self.progress), 'subtask')}, first {p.name}"
        ori = "" if math.isnan(p.orientation_error_deg) else f", {p.orientation_error_deg:.0f}°"
        line = (f"{self.index + 1}/{len(self.progress)} {p.name}: {p.position_error_m:.2f} m{ori} "
                f"after {p.elapsed_s:.1f} s")
        return f"{line}: {p.message}" if p.no_path or p.blocked is not None else line

    def skip(self, t: float) -> bool:
        """The operator skips the active subtask at time t: it is marked skipped and the next one begins at the
        next update. False when nothing is active (finished, failed or empty)."""
        if self.active is None:
            return False
        p = self.progress[self.index]
        self.progress[self.index] = replace(p, outcome=Outcome.SKIPPED, message="skipped by the operator",
                                            elapsed_s=p.elapsed_s if self._started_t is None else t - self._started_t,
                                            blocked=None)
        log.info("subtask %d %s skipped by the operator", self.index + 1, p.name)
        self.index += 1
        self._started_t = None
        return True

    # --- the loop ------------------------------------------------------------------------------

    def take_notices(self) -> list[str]:
        notices, self.notices = self.notices, []
        return notices

    def update(self, state: RobotState, occupied_points: np.ndarray | None, t: float,
               objects: MapObjects | None = None) -> References | None:
        """Advance the state machine and return references for the active subtask (None: stop); anchored
        targets are placed on their objects in `objects` (the latest map snapshot) every period."""
        if self._resume_pending:
            self.resume(t)
        authored = self.active
        if authored is None:
            return None
        started_t = self._started_t if self._started_t is not None else self._begin(state, t)
        sub, why = resolve_subtask(authored, objects)
        if sub is None:
            return self._wait(authored, state, t - started_t, why, objects)
        self._follow(authored, sub, state)
        pos_err, ori_err = self._errors(sub, state)
        elapsed = t - started_t
        tol = sub.tolerance
        within = pos_err <= tol.position_m and (math.isnan(ori_err) or ori_err <= tol.orientation_deg)
        if isinstance(sub, EESubtask) and self._ee_waypoint < len(sub.waypoints):
            within = False  # intermediate EE waypoints are passed, not dwelt at
        not_settled = settling(authored, objects, self.params.anchor_settle_m) if within else ""
        not_settled = self._base_settled_enough(sub, not_settled, t)
        self._note_settling(not_settled)
        if not_settled:
            within = False  # the goal is followed, but not reached on a map still settling
        self._held_since = (self._held_since if self._held_since is not None else t) if within else None
        held = 0.0 if self._held_since is None else t - self._held_since
        self._set_progress(Outcome.ACTIVE, elapsed, held, pos_err, ori_err)
        if within and held >= sub.dwell_s - 1e-9:
            self._set_progress(Outcome.DONE, elapsed, held, pos_err, ori_err, "reached")
            log.info("subtask %d %s done after %.1f s", self.index + 1, self.progress[self.index].name, elapsed)
            self.index += 1
            self._started_t = None
            return self.update(state, occupied_points, t, objects)
        if elapsed > sub.timeout_s:
            p = self.progress[self.index]
            why = "no path to the goal; " if p.no_path else "blocked; " if p.blocked is not None else ""
            why = f"{not_settled}; {why}" if not_settled else why
            ori = "" if math.isnan(ori_err) else f", {ori_err:.0f}°"  # 0.01 m off may fail by its heading
            msg = f"timed out after {sub.timeout_s:g} s ({why}{pos_err:.2f} m{ori} from the goal)"
            self._set_progress(Outcome.FAILED, elapsed, held, pos_err, ori_err, msg)
            log.warning("subtask %d failed: %s", self.index + 1, msg)
            return None
        refs = self._references(sub, state, occupied_points, t)
        if isinstance(sub, BaseSubtask):
            self._watch_stall(self._distance_to_go(pos_err), pos_err, state, occupied_points, t)
        self._switched = False
        return refs

    def _begin(self, state: RobotState, t: float) -> float:
        """Start the active subtask at time t (returned)."""
        self._started_t = t
        self._held_since = None
        self._unsettled_since = None
        self._settle_told = False
        self._switched = True
        self.path = None
        self._s_progress = 0.0
        self._plan_t = -math.inf
        self._grid_sig = None
        sub = self.active
        self._anchor_goal = None
        if sub is not None and is_anchored(sub):
            self._hold_base = state.q[:3].copy()  # the stance is set where the anchor is placed (`_follow`)
        elif isinstance(sub, EESubtask) and sub.frame == "world":
            reach = float(np.hypot(*self.ee_offset_base[:2]))
            self._hold_base = manipulation_stance(np.array(sub.goal().position), state.q[:3], reach)
        else:  # base subtasks, and EE targets in the base frame (only the arm moves)
            self._hold_base = state.q[:3].copy()
        self._ee_waypoint = 0
        self._base_waypoint = 0
        self._best_error = math.inf
        self._improved_t = t
        self._turning = None
        return t

    def _distance_to_go(self, pos_err: float) -> float:
        """What is left of the planned path (through the waypoints still ahead), or the straight-line error
        without one: a route round an island first leads away from its goal, and that is progress."""
        path = self.path
        if path is None or len(path) < 2:
            return pos_err
        return max(float(path_arclength(path)[-1]) - self._s_progress, 0.0)

    def _watch_stall(self, to_go: float, pos_err: float, state: RobotState, occupied: np.ndarray | None,
                     t: float) -> None:
        """Blocked: the base's distance to go along its plan (`_distance_to_go`) has not fallen by
        `stall_progress_m` for `stall_s`; the message names the distance to the goal and to the nearest
        occupied point (cleared once the base makes progress again)."""
        p = self.progress[self.index]
        if to_go < self._best_error - self.params.stall_progress_m:
            self._best_error, self._improved_t = to_go, t
            if p.blocked is not None:
                self.progress[self.index] = replace(p, blocked=None, message="")
            return
        stalled = t - self._improved_t
        if stalled < self.params.stall_s or p.no_path:
            return
        xy, dist = nearest_obstacle_point(occupied, state.q[:2], self.params.obstacle_z_m)
        blocked = Blocked(stalled, xy, dist)
        near = "" if xy is None else f"; nearest obstacle {dist:.2f} m away at ({xy[0]:.2f}, {xy[1]:.2f})"
        message = f"blocked: no progress for {stalled:.0f} s, {pos_err:.2f} m from the goal{near}"
        if p.blocked is None:
            log.warning("subtask %d %s: %s", self.index + 1, p.name, message)
        self.progress[self.index] = replace(p, blocked=blocked, message=message)

    def _wait(self, sub: BaseSubtask | EESubtask, state: RobotState, elapsed: float, why: str,
              objects: MapObjects | None) -> References | None:
        """An anchored target that cannot be placed (its object not in the map, not seen yet, or ambiguous):
        the base holds where it is, turning in place to face where the object was last mapped (or declared) so
        that its cameras may find it again, and the hand goes to its ready pose, never toward where the object
        was; past `timeout_s` the subtask fails with the reason."""
        self._held_since = None
        self._anchor_goal = None
        self.path = None
        nan = math.nan
        if elapsed > sub.timeout_s:
            msg = f"timed out after {sub.timeout_s:g} s: {why}"
            self._set_progress(Outcome.FAILED, elapsed, 0.0, nan, nan, msg)
            log.warning("subtask %d failed: %s", self.index + 1, msg)
            return None
        message = f"{why}: waiting"
        if self.progress[self.index].message != message:
            log.info("subtask %d: %s", self.index + 1, message)
        self._set_progress(Outcome.ACTIVE, elapsed, 0.0, nan, nan, message)
        self.progress[self.index] = replace(self.progress[self.index], anchored_goal=None)
        refs = navigation_references(state.q[None, :2].copy(), 0.0, float(state.q[2]), _facing(sub, state, objects),
                                     self.ready, self.params, self.n_nodes, self.dt, ("base", "ee"), self._switched)
        self._switched = False
        return refs

    def _base_settled_enough(self, sub: BaseSubtask | EESubtask, not_settled: str, t: float) -> str:
        """`not_settled`, or '' for a base subtask held at its goal on an unsettled object for
        `anchor_base_settle_s`: the stance then completes on the map's box as it is (the operator is told). From the
        goal no camera may see a moved box's old place, which then stays fused for good; a hand target on the box
        keeps waiting, its camera above the box sees the old place and the map settles."""
        if not not_settled:
            return ""
        self._unsettled_since = t if self._unsettled_since is None else self._unsettled_since
        if not isinstance(sub, BaseSubtask) or t - self._unsettled_since < self.params.anchor_base_settle_s - 1e-9:
            return not_settled
        if not self._settle_told:
            self._settle_told = True
            note = f"{not_settled} after {self.params.anchor_base_settle_s:g} s at the goal: the stance completes on it"
            log.info("subtask %d: %s", self.index + 1, note)
            self.notices.append(note)
        return ""

    def _note_settling(self, why: str) -> None:
        """Show why an anchored goal within tolerance does not complete (its object's map has not settled), and
        take the reason back once it has (`why` '')."""
        current = self.progress[self.index].message
        message = f"{why}: waiting" if why else ("" if _settling_message(current) else current)
        if current != message:
            if why:
                log.info("subtask %d: %s", self.index + 1, message)
            self.progress[self.index] = replace(self.progress[self.index], message=message)

    def _follow(self, authored: BaseSubtask | EESubtask, sub: BaseSubtask | EESubtask, state: RobotState) -> None:
        """Keep an anchored goal on its object: where it is placed first, the stance (EE) is set; moved more
        than `anchor_follow_m` since, the plan and the A* path are re-made and the operator is told."""
        anchor = anchor_of(authored)
        if not is_anchored(authored):
            return
        goal = sub.goal()
        at = np.array([goal.x, goal.y, 0.0]) if isinstance(goal, BasePose) else np.array(goal.position, float)
        p = self.progress[self.index]
        self.progress[self.index] = replace(p, anchored_goal=(float(at[0]), float(at[1]), float(at[2])))
        moved = math.inf if self._anchor_goal is None else float(np.linalg.norm(at - self._anchor_goal))
        if moved <= self.params.anchor_follow_m:
            return
        if self._anchor_goal is None and p.message.endswith(": waiting"):
            self.progress[self.index] = replace(self.progress[self.index], message="")  # placed: no longer waiting
        if self._anchor_goal is not None and anchor is not None:
            note = f"{anchor.object} moved {moved:.2f} m: target follows"
            self.notices.append(note)
            log.info("subtask %d: %s", self.index + 1, note)
            self.progress[self.index] = replace(self.progress[self.index], message=note)
        self._anchor_goal = at
        self._plan_t = -math.inf  # re-plan the base path now
        if isinstance(sub, EESubtask):
            reach = float(np.hypot(*self.ee_offset_base[:2]))
            self._hold_base = manipulation_stance(at, state.q[:3], reach)

    def _set_progress(self, outcome: Outcome, elapsed: float, held: float, pos: float, ori: float,
                      message: str | None = None) -> None:
        p = self.progress[self.index]
        self.progress[self.index] = replace(
            p, outcome=outcome, elapsed_s=elapsed, held_s=held, position_error_m=pos, orientation_error_deg=ori,
            message=p.message if message is None else message)

    def _errors(self, sub: BaseSubtask | EESubtask, state: RobotState) -> tuple[float, float]:
        if isinstance(sub, BaseSubtask):
            goal = sub.goal()
            shift = self.progress[self.index].goal_shift
            xy = np.array(shift.driven) if shift is not None else goal.xy()
            pos = float(np.hypot(*(state.q[:2] - xy)))
            ori = math.nan if goal.yaw_rad is None else abs(math.degrees(wrap_angle(state.q[2] - goal.yaw_rad)))
            return pos, ori
        T = self.robot.ee_pose(state.q)
        if sub.frame == "base":
            T = np.linalg.inv(self.robot.frame_pose(state.q, "mobile_base")) @ T
        target = sub.path()[min(self._ee_waypoint, len(sub.path()) - 1)]
        pos = float(np.linalg.norm(T[:3, 3] - np.array(target.position)))
        if self._ee_waypoint < len(sub.waypoints) and pos <= sub.tolerance.position_m:
            self._ee_waypoint += 1
        goal = sub.goal()
        R = goal.rotation()
        ori = math.nan if R is None else _angle_between(T[:3, :3], R)
        pos_goal = float(np.linalg.norm(T[:3, 3] - np.array(goal.position)))
        return pos_goal, ori

    def _references(self, sub: BaseSubtask | EESubtask, state: RobotState, occupied: np.ndarray | None,
                    t: float) -> References:
        order = tuple(sub.order)
        if isinstance(sub, EESubtask):
            target = sub.path()[min(self._ee_waypoint, len(sub.path()) - 1)]
            if self._turning_now(order, state):
                return turn_references(self._hold_base, self._switched)
            return manipulation_references(np.array(target.position), target.rotation(), self._hold_base, order,
                                           self._switched, frame=sub.frame)
        path = self._maybe_replan(sub, state, occupied, t)
        s = path_arclength(path)
        self._s_progress = project_on_path(path, s, state.q[:2], self._s_progress)
        self._pass_waypoints(sub, state.q[:2], path, s)
        hold = None if sub.ee is None else (np.array(sub.ee.position), sub.ee.rotation())
        return navigation_references(path, self._s_progress, float(state.q[2]), sub.goal().yaw_rad,
                                     self.ready, self.params, self.n_nodes, self.dt, order, self._switched,
                                     ee_hold=hold)

    def _turning_now(self, order: tuple[str, ...], state: RobotState) -> bool:
        """Whether an EE subtask's base is still turning into its stance first (decided at the first references,
        where the stance is set; once within `stance_turn_deg` the subtask's own order, for good; never when the
        base's task already leads): `tasks/stance_turn.py`."""
        if not order or order[0] == "base":
            return False
        far = needs_turn(float(state.q[2]), float(self._hold_base[2]), self.params.stance_turn_deg)
        if self._turning is None:
            self._turning = far
        elif self._turning and not far:
            self._turning = False
            self._switched = True  # a new order: the controller iterates more on the switch
        return self._turning

    def _maybe_replan(self, sub: BaseSubtask, state: RobotState, occupied: np.ndarray | None,
                      t: float) -> np.ndarray:
        """The base's path to the subtask's goals: the current one, or a new plan when the map changed or
        the re-plan period passed."""
        sig, p = None, self.params
        if occupied is not None:  # the cheap grid notices a change; the plan is made on the fine one
            sig = OccupancyGrid.from_points(occupied, p.plan_bounds_m, p.grid_cell_m, self._inflations_m()[0],
                                            p.obstacle_z_m, subcells=1).signature()
        due = t - self._plan_t >= self.params.replan_period_s
        if self.path is not None and sig == self._grid_sig and not due:
            return self.path
        goals = [w.xy() for w in sub.path()[self._base_waypoint:]]
        notes: list[str] = []
        shift = None
        no_path = False
        try:
            if occupied is not None:
                path, notes = self._plan(occupied, state.q[:2], goals)
                shift = _goal_shift(goals[-1], path[-1])  # a blocked final goal is moved to a free cell
            else:
                path = np.array([state.q[:2], *goals])
            notes = [n for n in notes if not n.startswith("goal (")]
            if shift is not None:
                notes.append(f"goal moved {shift.distance_m:.2f} m to ({shift.driven[0]:.2f}, {shift.driven[1]:.2f}) "
                             "to clear an obstacle")
            message = "; ".join(notes)
        except NoPathError as err:
            path = state.q[None, :2].copy()  # hold here until the map changes (a box moves away)
            message = f"{err}: holding here (Skip the subtask or Stop)"
            no_path = True
        self.path = path
        self._s_progress = 0.0
        self._plan_t, self._grid_sig = t, sig
        p = self.progress[self.index]
        if (p.blocked is not None or _settling_message(p.message)) and not no_path and not notes:
            message = p.message  # a stall's or a settling wait's message stays until it is over
        if message != p.message or shift != p.goal_shift or no_path != p.no_path:
            if (shift is not None and shift != p.goal_shift) or (no_path and not p.no_path):
                log.info("subtask %d: %s", self.index + 1, message)
            self.progress[self.index] = replace(p, message=message, goal_shift=shift, no_path=no_path,
                                                blocked=None if no_path else p.blocked)
        return path

    def _plan(self, occupied: np.ndarray, start_xy: np.ndarray, goals: list[np.ndarray]
              ) -> tuple[np.ndarray, list[str]]:
        """A path with the preferred clearance (`inflation_m`), or, where that leaves no path or skips a
        waypoint, with the least the base needs (`inflation_min_m`); raises `NoPathError` when neither has one."""
        p = self.params
        best: tuple[np.ndarray, list[str], int] | None = None
        error: NoPathError | None = None
        preferred, least = self._inflations_m()
        for inflation in dict.fromkeys((preferred, least)):
            grid = OccupancyGrid.from_points(occupied, p.plan_bounds_m, p.grid_cell_m, inflation, p.obstacle_z_m)
            notes: list[str] = []
            try:
                path = plan_path(grid, start_xy, goals, notes=notes, first_waypoint=self._base_waypoint + 1)
            except NoPathError as err:
                error = err
                continue
            skipped = sum("skipped" in n for n in notes)
            if best is None or skipped < best[2]:
                if inflation < preferred:
                    notes.append(f"a narrow passage: planned with {inflation:.2f} m of clearance")
                best = (path, notes, skipped)
            if skipped == 0:
                break
        if best is None:
            raise error or NoPathError("no path to the goal on the current map")
        return best[0], best[1]

    def _pass_waypoints(self, sub: BaseSubtask, xy: np.ndarray, path: np.ndarray, s: np.ndarray) -> None:
        """Mark intermediate base waypoints passed, so a re-plan never leads back to one.

        Passed: the base came within `waypoint_pass_m` of it, or its progress along the plan is beyond the
        plan's point nearest to it (smoothed paths cut corners; a skipped waypoint is never reached)."""
        if len(path) < 2:
            return
        while self._base_waypoint < len(sub.waypoints):
            w = sub.waypoints[self._base_waypoint].xy()
            near = float(np.hypot(*(xy - w))) <= self.params.waypoint_pass_m
            if not (near or self._s_progress >= project_on_path(path, s, w)):
                return
            self._base_waypoint += 1
