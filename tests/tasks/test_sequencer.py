"""The sequencer's state machine and references, driven by hand-made robot states."""

import math

import numpy as np
import pytest

from core.robot.model import READY_Q
from core.types import References, RobotState
from tasks import BasePose, BaseSubtask, EEPose, EESubtask, TaskSequence, Tolerance
from tasks.sequencer import Outcome, Sequencer


def state_at(x: float, y: float, yaw: float = 0.0, arm=None) -> RobotState:
    q = READY_Q.copy()
    q[:3] = x, y, yaw
    if arm is not None:
        q[3:] = arm
    return RobotState(0.0, q, np.zeros(9))


def test_base_subtask_references_follow_the_path(robot):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0, yaw_deg=90.0))])
    s = Sequencer(robot, seq)
    refs = s.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    assert refs.order == ("base", "posture") and refs.switched
    assert refs.base.xy.shape == (11, 2) and refs.ee is None and refs.posture.shape == (11, 6)
    steps = np.linalg.norm(np.diff(refs.base.xy, axis=0), axis=1)
    np.testing.assert_allclose(steps, 0.6 * 0.3, atol=1e-6)  # nominal speed × dt
    np.testing.assert_allclose(refs.base.yaw, 0.0, atol=1e-6)  # heading along the path
    # the arm holds its ready pose: the hand camera looks ahead and down at the path
    np.testing.assert_allclose(refs.posture, np.tile(READY_Q[3:], (11, 1)), atol=1e-9)
    axis = robot.ee_pose(np.concatenate([[0.0, 0.0, 0.0], refs.posture[0]]))[:3, 0]
    assert axis[0] > 0.5 and axis[2] < 0.0
    assert not s.update(state_at(0.1, 0.0), np.zeros((0, 3)), 0.1).switched
    near = s.update(state_at(3.6, 0.0), np.zeros((0, 3)), 0.2)
    assert near.base.yaw[-1] == pytest.approx(math.pi / 2)  # goal yaw near the end


def test_completion_needs_tolerance_and_dwell(robot):
    target = EEPose(position=(1.0, 0.2, 0.9))
    seq = TaskSequence(subtasks=[EESubtask(target=target, dwell_s=1.0, tolerance=Tolerance(position_m=0.5))])
    s = Sequencer(robot, seq)
    st = state_at(0.0, 0.0)
    assert s.update(st, None, 0.0) is not None
    assert s.progress[0].outcome == Outcome.ACTIVE
    assert s.update(st, None, 0.5) is not None
    assert s.update(st, None, 1.01) is None
    assert s.finished and s.progress[0].outcome == Outcome.DONE
    assert "finished" in s.status_line()


def test_timeout_fails_with_clear_status(robot):
    seq = TaskSequence(subtasks=[BaseSubtask(name="far", target=BasePose(x=10.0, y=0.0), timeout_s=5.0),
                                 BaseSubtask(target=BasePose(x=0.0, y=0.0))])
    s = Sequencer(robot, seq)
    assert s.update(state_at(0.0, 0.0), None, 0.0) is not None
    assert s.update(state_at(0.0, 0.0), None, 5.1) is None
    assert s.failed and s.progress[0].outcome == Outcome.FAILED and s.progress[1].outcome == Outcome.PENDING
    assert "timed out" in s.status_line() and "far" in s.status_line()


def test_a_timeout_says_the_heading_that_failed_it(robot):
    """At the goal's position but turned away: the message gives the angle, not only '0.00 m from the goal'
    (the aisle's lap-2 pick read 'timed out after 30 s (0.01 m from the goal)')."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=0.0, y=0.0, yaw_deg=90.0), timeout_s=5.0)])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), None, 0.0)
    assert s.update(state_at(0.0, 0.0), None, 5.1) is None
    assert s.progress[0].message == "timed out after 5 s (0.00 m, 90° from the goal)"


def test_manipulation_stance_and_ee_first(robot):
    seq = TaskSequence(subtasks=[EESubtask(target=EEPose(position=(2.5, 0.0, 0.8), rpy_deg=(0, 90, 0)))])
    s = Sequencer(robot, seq)
    refs = s.update(state_at(0.0, 0.0, 0.3), None, 0.0)
    assert refs.order == ("ee", "base")
    reach = np.hypot(*s.ee_offset_base[:2])
    np.testing.assert_allclose(refs.base.xy[0], [2.5 - reach, 0.0], atol=1e-9)  # target at comfortable reach
    assert refs.base.yaw[0] == pytest.approx(0.0)  # facing the target
    np.testing.assert_allclose(refs.ee.rotation[0][:, 0], [0, 0, -1], atol=1e-12)
    near = Sequencer(robot, seq).update(state_at(2.0, 0.0, 0.3), None, 0.0)
    np.testing.assert_allclose(near.base.xy[0], [2.0, 0.0])  # already within reach: stay


def test_a_target_beside_the_base_turns_the_base_into_its_stance_before_the_hand_reaches(robot):
    """The aisle's picks: the base stands side-on to a target 1.05 m to its side. The base's task leads, the arm at
    its ready joints, until the base has turned within `stance_turn_deg` of the stance (facing the target); then the
    hand's task leads, for good (a switch: the controller iterates more). A target ahead starts with the hand's task
    first (`tasks/stance_turn.py`)."""
    seq = TaskSequence(subtasks=[EESubtask(target=EEPose(position=(-0.75, 1.4, 1.5), rpy_deg=(0, 90, 180)))])
    s = Sequencer(robot, seq)

    def refs_at(yaw_deg: float, t: float, y: float = 2.45) -> References:
        refs = s.update(state_at(-0.75, y, math.radians(yaw_deg)), None, t)
        assert refs is not None and refs.base is not None
        return refs

    first = refs_at(180.0, 0.0)
    assert first.order == ("base", "posture") and first.ee is None and first.posture is not None
    assert first.base is not None and first.base.yaw is not None
    assert first.base.yaw[0] == pytest.approx(3 * math.pi / 2)  # facing the target: a quarter turn away
    turning = refs_at(230.0, 0.5)
    assert turning.order == ("base", "posture") and not turning.switched  # 40° to go
    turned = refs_at(255.0, 1.0)
    assert turned.order == ("ee", "base") and turned.ee is not None and turned.switched  # within 20°: the hand reaches
    later = refs_at(230.0, 1.5, y=2.40)
    assert later.order == ("ee", "base") and not later.switched  # once turned, the hand keeps the lead
    ahead = TaskSequence(subtasks=[EESubtask(target=EEPose(position=(2.5, 0.0, 0.8), rpy_deg=(0, 90, 0)))])
    refs = Sequencer(robot, ahead).update(state_at(0.0, 0.0, 0.3), None, 0.0)
    assert refs is not None and refs.order == ("ee", "base")


def test_path_replans_around_new_obstacles(robot):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0))])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    straight = s.path.copy()
    rng = np.random.default_rng(0)
    wall = rng.uniform([1.8, -0.8, 0.1], [2.2, 0.8, 0.6], (500, 3))
    s.update(state_at(0.0, 0.0), wall, 0.1)  # map changed: re-planned at once
    assert np.abs(s.path[:, 1]).max() > 1.0 > np.abs(straight[:, 1]).max()


def test_passed_waypoints_are_not_revisited_on_replan(robot):
    """A re-plan after a waypoint was passed (here round a corner) leads on, never back to it."""
    corner = BasePose(x=3.0, y=0.0)
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.0, y=3.0), waypoints=[corner])])
    s = Sequencer(robot, seq)
    free = np.zeros((0, 3))
    s.update(state_at(0.0, 0.0), free, 0.0)
    assert np.linalg.norm(s.path - [3.0, 0.0], axis=1).min() < 0.05  # the plan goes through the corner
    s.update(state_at(2.7, 0.5, math.pi / 2), free, 0.5)  # cut the corner, within waypoint_pass_m
    s.update(state_at(2.9, 1.2, math.pi / 2), free, 2.0)  # re-plan is due
    assert s.path[:, 1].min() > 1.0  # straight on to the goal: the corner is not visited again
    assert s.path[-1] == pytest.approx([3.0, 3.0])


def test_waypoint_passed_along_the_plan_without_coming_close(robot):
    """A waypoint the smoothed plan passes wide of counts as passed once the base is beyond it on the plan."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=6.0, y=0.0), waypoints=[BasePose(x=3.0, y=1.0)])])
    s = Sequencer(robot, seq)
    free = np.zeros((0, 3))
    s.update(state_at(0.0, 0.0), free, 0.0)
    s.path = np.array([[0.0, 0.0], [6.0, 0.0]])  # a plan 1 m wide of the waypoint
    s.update(state_at(3.5, 0.0), free, 0.1)
    s.update(state_at(3.5, 0.0), free, 1.5)
    assert s.path[:, 1].max() < 0.05  # re-planned straight to the goal


def test_empty_sequence_returns_nothing(robot):
    s = Sequencer(robot, TaskSequence())
    assert s.update(state_at(0, 0), None, 0.0) is None
    assert s.status_line() == "no subtasks"


def test_a_moved_goal_completes_where_the_base_was_sent(robot):
    """The goal is 0.7 m from a box (the base keeps 0.8 m): the planner moves it to a free cell, and reaching
    that cell completes the subtask (judged against the authored goal it timed out 0.1 m short)."""
    box = np.random.default_rng(1).uniform([3.0, 0.7, 0.1], [3.4, 1.1, 0.6], (400, 3))
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.2, y=0.0), timeout_s=30.0,
                                             tolerance=Tolerance(position_m=0.05))])
    s = Sequencer(robot, seq)
    assert s.update(state_at(0.0, 0.0), box, 0.0) is not None
    shift = s.progress[0].goal_shift
    assert shift is not None and shift.original == (3.2, 0.0)
    assert 0.05 < shift.distance_m < 0.3 and shift.driven[1] < 0.0  # away from the box
    assert f"goal moved {shift.distance_m:.2f} m" in s.progress[0].message
    assert s.path[-1] == pytest.approx(shift.driven)
    at = state_at(*shift.driven)
    assert s.update(at, box, 1.0) is None and s.finished
    no_box = Sequencer(robot, seq)
    no_box.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    assert no_box.progress[0].goal_shift is None


def test_ee_target_in_the_base_frame(robot):
    """An EE target in the base frame is judged relative to the base, wherever it stands; the references say
    so (the controller holds it relative to the base over the horizon); the base holds its stance."""
    st = state_at(2.0, -1.0, 1.0)
    T_rel = np.linalg.inv(robot.frame_pose(st.q, "mobile_base")) @ robot.ee_pose(st.q)
    target = EEPose(position=tuple(T_rel[:3, 3]), frame="base")
    seq = TaskSequence(subtasks=[EESubtask(target=target, tolerance=Tolerance(position_m=0.01), dwell_s=0.5)])
    s = Sequencer(robot, seq)
    refs_state = state_at(5.0, 3.0, -2.0)  # elsewhere: the target moves with the base
    refs = s.update(refs_state, None, 0.0)
    assert refs.ee.frame == "base" and refs.ee.position[0] == pytest.approx(T_rel[:3, 3])
    np.testing.assert_allclose(refs.base.xy[0], [5.0, 3.0])  # the base holds where it is
    assert s.progress[0].position_error_m < 1e-9  # the arm pose is the same relative to the base
    assert s.update(refs_state, None, 0.6) is None and s.finished


def test_base_subtask_holds_the_hand_in_the_base_frame(robot):
    hold = EEPose(position=(0.4, -0.55, 1.0), rpy_deg=(0.0, 0.0, -90.0), frame="base")
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), ee=hold)])
    refs = Sequencer(robot, seq).update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    assert refs.order == ("base", "ee") and refs.ee.frame == "base"
    np.testing.assert_allclose(refs.ee.position, [[0.4, -0.55, 1.0]])
    np.testing.assert_allclose(refs.ee.rotation[0], hold.rotation())
    assert refs.base.xy.shape == (11, 2)  # the base still follows its path


def test_paused_time_counts_toward_neither_timeout_nor_dwell(robot):
    """A real robot's clock runs on while the run is paused: 9 s paused within an 8 s timeout is no failure."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=8.0, dwell_s=1.0)])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    s.update(state_at(0.5, 0.0), np.zeros((0, 3)), 2.0)
    s.pause(2.0)
    s.resume(11.0)
    assert s.update(state_at(0.6, 0.0), np.zeros((0, 3)), 11.5) is not None
    assert s.progress[0].outcome == Outcome.ACTIVE and s.progress[0].elapsed_s == pytest.approx(2.5)
    s.update(state_at(4.0, 0.0), np.zeros((0, 3)), 12.0)  # at the goal: the dwell starts
    s.pause(12.5)
    s.pause(13.0)  # a second pause while paused changes nothing
    s.resume(20.0)
    s.update(state_at(4.0, 0.0), np.zeros((0, 3)), 20.2)
    assert s.progress[0].outcome == Outcome.ACTIVE and s.progress[0].held_s == pytest.approx(0.7)
    s.update(state_at(4.0, 0.0), np.zeros((0, 3)), 20.6)
    assert s.progress[0].outcome == Outcome.DONE
    s.update(state_at(4.0, 0.0), np.zeros((0, 3)), 21.0)
    s.resume(30.0)  # resume without a pause: nothing to shift
    assert s.finished


def test_a_resume_without_a_time_counts_the_pause_up_to_the_next_state(robot):
    """Start after a silent driver: the clock read at Start is still the old one, so the pause ends at the time
    of the next state the robot reports (here 9 s later), not at Start's stale reading."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=8.0)])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    s.update(state_at(0.5, 0.0), np.zeros((0, 3)), 2.0)
    s.pause(2.0)
    s.resume()
    assert s.update(state_at(0.6, 0.0), np.zeros((0, 3)), 11.0) is not None
    assert s.progress[0].elapsed_s == pytest.approx(2.0)
    s.update(state_at(0.7, 0.0), np.zeros((0, 3)), 11.5)
    assert s.progress[0].elapsed_s == pytest.approx(2.5)
    s.pause(12.0)
    s.resume()
    s.pause(13.0)  # paused again before any state came: still paused since 12 s
    s.resume(20.0)
    s.update(state_at(0.8, 0.0), np.zeros((0, 3)), 20.5)
    assert s.progress[0].outcome == Outcome.ACTIVE and s.progress[0].elapsed_s == pytest.approx(3.5)


def test_without_the_pause_the_same_wait_times_out(robot):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=8.0)])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0)
    assert s.update(state_at(0.6, 0.0), np.zeros((0, 3)), 11.5) is None
    assert s.progress[0].outcome == Outcome.FAILED and "timed out" in s.progress[0].message


def pen(centre=(3.0, 0.0), half=1.2, n=400, seed=0) -> np.ndarray:
    """Points on the four walls of a closed square pen (0.6 m high) around `centre`."""
    rng = np.random.default_rng(seed)
    s = rng.uniform(-half, half, n)
    z = rng.uniform(0.1, 0.6, n)
    c = np.asarray(centre)
    lo, hi = np.full(n, -half), np.full(n, half)
    walls = [np.column_stack([c[0] + a, c[1] + b, z]) for a, b in ((s, lo), (s, hi), (lo, s), (hi, s))]
    return np.concatenate(walls)


def test_no_path_is_said_at_once_and_the_base_holds(robot):
    """A goal inside a closed pen: the first update says "no path to the goal" and the references hold the base."""
    seq = TaskSequence(subtasks=[BaseSubtask(name="into the pen", target=BasePose(x=3.0, y=0.0), timeout_s=60.0)])
    s = Sequencer(robot, seq)
    refs = s.update(state_at(0.0, 0.0), pen(), 0.0)
    p = s.progress[0]
    assert p.no_path and p.outcome == Outcome.ACTIVE
    assert p.message.startswith("no path to the goal (3.00, 0.00)") and "Skip" in p.message
    assert "no path to the goal" in s.status_line() and "nan" not in s.status_line()
    np.testing.assert_allclose(refs.base.xy, 0.0, atol=1e-9)  # hold where it is
    s.update(state_at(0.0, 0.0), pen(), 61.0)
    assert s.failed and "no path to the goal" in s.progress[0].message


def test_no_path_to_a_waypoint_names_it(robot):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=0.0, y=3.0), waypoints=[BasePose(x=3.0, y=0.0)])])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), pen(), 0.0)
    assert s.progress[0].no_path and s.progress[0].message.startswith("no path to waypoint 1 (3.00, 0.00)")


def test_skip_goes_on_with_the_next_subtask(robot):
    seq = TaskSequence(subtasks=[BaseSubtask(name="into the pen", target=BasePose(x=3.0, y=0.0)),
                                 BaseSubtask(name="back", target=BasePose(x=0.0, y=0.0))])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), pen(), 0.0)
    assert s.skip(1.0)
    assert s.progress[0].outcome == Outcome.SKIPPED and s.index == 1
    assert s.update(state_at(0.0, 0.0), pen(), 1.1) is None  # already at the second goal
    assert s.finished and "1 skipped" in s.status_line()
    assert not s.skip(2.0)


def test_a_base_that_makes_no_progress_says_blocked_with_the_nearest_obstacle(robot):
    """The goal is reachable on the map but the base stands still: after `stall_s` the subtask says blocked, with
    the nearest obstacle; moving on clears it."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=60.0)])
    s = Sequencer(robot, seq)
    post = np.array([[0.0, 1.5, 0.3]])
    for t in np.arange(0.0, 9.5, 0.5):
        s.update(state_at(0.0, 0.0), post, t)
        assert s.progress[0].blocked is None
    s.update(state_at(0.0, 0.0), post, 10.5)
    p = s.progress[0]
    assert p.blocked is not None and p.blocked.obstacle_xy == pytest.approx((0.0, 1.5))
    assert p.message.startswith("blocked: no progress for 10 s, 4.00 m from the goal; nearest obstacle 1.50 m away")
    assert "blocked" in s.status_line()
    s.update(state_at(1.0, 0.0), post, 11.0)
    assert s.progress[0].blocked is None and "blocked" not in s.progress[0].message


def test_a_route_that_first_leads_away_from_the_goal_is_progress_not_blocked(robot):
    """Round an island through a waypoint behind the start: for 12 s the base drives away from its goal, so
    the straight-line error grows; the distance to go along the plan falls, and nothing says blocked."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.0, y=0.0), waypoints=[BasePose(x=-4.0, y=3.0),
                                                                                         BasePose(x=3.0, y=3.0)],
                                             timeout_s=120.0)])
    s = Sequencer(robot, seq)
    for t in np.arange(0.0, 12.0, 0.5):
        xy = np.array([0.0, 0.0]) + (t / 12.0) * np.array([-4.0, 3.0])
        s.update(state_at(*xy, yaw=2.5), np.zeros((0, 3)), t)
        assert s.progress[0].blocked is None, (t, s.progress[0].message)
    assert s.progress[0].position_error_m > 3.0 + 4.0  # farther from the goal than at the start


def test_the_planner_grows_its_obstacles_by_the_controllers_margin_growth(robot):
    """A 1.8 m gap: planned with the preferred 0.8 m of clearance. The controller's delta_safe grown by 0.1 m (an
    uncertain pose): the planner's obstacles grow as much and it plans again at once, 0.9 m closes the gap and
    the least (0.75 m) passes, a narrow passage; grown by 0.3 m, neither passes: no path where the controller could
    not keep its margin."""
    ys = np.arange(0.9, 8.0, 0.05)
    side = np.c_[np.full(len(ys), 2.0), ys, np.full(len(ys), 0.3)]
    walls = np.concatenate([side, side * [1, -1, 1]])
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=60.0)])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), walls, 0.0)
    assert not s.progress[0].no_path and "narrow passage" not in s.progress[0].message
    s.set_margin_growth(0.1)  # 0.9 m: only the least (0.75 m) passes, and the operator is told
    s.update(state_at(0.0, 0.0), walls, 0.1)
    assert not s.progress[0].no_path and "narrow passage: planned with 0.75 m" in s.progress[0].message
    s.set_margin_growth(0.3)
    s.update(state_at(0.0, 0.0), walls, 0.2)
    assert s.progress[0].no_path
    with pytest.raises(ValueError, match="margin growth"):
        s.set_margin_growth(float("nan"))


def test_a_passage_too_narrow_for_the_preferred_clearance_is_planned_with_the_least_the_base_needs(robot):
    """A 1.5 m gap between two walls: no path with 0.8 m of clearance (0 m left), one with 0.65 m (0.2 m left);
    the operator is told it is a narrow passage. A gap of 1.2 m is too narrow even for that: no path."""
    def walls(gap_m: float) -> np.ndarray:
        ys = np.arange(gap_m / 2, 8.0, 0.05)  # to the edge of the planning grid: no way round
        side = np.c_[np.full(len(ys), 2.0), ys, np.full(len(ys), 0.3)]
        return np.concatenate([side, side * [1, -1, 1]])

    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=60.0)])
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), walls(1.5), 0.0)
    p = s.progress[0]
    assert not p.no_path and "narrow passage: planned with 0.65 m of clearance" in p.message
    assert np.all(np.abs(s.path[np.abs(s.path[:, 0] - 2.0) < 0.05, 1]) < 0.1)  # through the gap's middle
    s = Sequencer(robot, seq)
    s.update(state_at(0.0, 0.0), walls(1.2), 0.0)
    assert s.progress[0].no_path
