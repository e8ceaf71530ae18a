"""While the base drives the arm holds its ready joints, the pan turned toward the path ahead within its limit and
wrist 1 tilting the hand camera down onto the look-ahead point."""

import numpy as np

from core.params import SequencerParams
from core.robot.model import READY_Q, RobotModel
from tasks.ready_hand import ReadyHand
from tasks.references import navigation_references


def test_the_ready_joints_turn_only_the_pan_and_a_point_straight_ahead_needs_no_turn():
    hand = ReadyHand.of(RobotModel())
    q = hand.joints(np.array([-0.4, 0.0, 0.7]))
    np.testing.assert_allclose(q[:, 1:], np.tile(READY_Q[4:], (3, 1)))
    np.testing.assert_allclose(q[:, 0], READY_Q[3] + np.array([-0.4, 0.0, 0.7]))
    assert abs(hand.heading_rad) < 1e-6  # the ready hand camera looks along the base's x
    np.testing.assert_allclose(hand.bearing_to(np.array([[2.0, 0.0], [0.27, 1.0]])), [0.0, np.pi / 2], atol=1e-6)


def test_navigation_holds_the_posture_and_turns_it_into_a_turn_within_its_limit():
    hand = ReadyHand.of(RobotModel())
    params = SequencerParams()
    straight = np.array([[0.0, 0.0], [6.0, 0.0]])
    left_turn = np.array([[0.0, 0.0], [0.3, 0.0], [0.3, 5.0]])  # a sharp left just ahead
    refs = navigation_references(straight, 0.0, 0.0, None, hand, params, 10, 0.1, ("base", "ee"), False)
    assert refs.order == ("base", "posture") and refs.ee is None and refs.posture is not None
    straight_q = np.tile(READY_Q[3:], (11, 1))
    straight_q[:, 3] = refs.posture[:, 3]
    np.testing.assert_allclose(refs.posture, straight_q, atol=1e-9)  # straight: the ready pose, wrist 1 tilted
    turn = navigation_references(left_turn, 0.0, 0.0, None, hand, params, 10, 0.1, ("ee", "base"), False)
    assert turn.order == ("posture", "base") and turn.posture is not None
    pan = turn.posture[:, 0]
    assert pan[0] > np.radians(30)  # looks left, into the turn
    assert np.all(np.abs(pan) <= np.radians(params.lookahead_turn_max_deg) + 1e-9)
    held = navigation_references(straight, 0.0, 0.0, None, hand, params, 10, 0.1, ("base", "ee"), False,
                                 ee_hold=(np.array([0.6, 0.0, 1.0]), None))
    assert held.order == ("base", "ee") and held.ee is not None and held.posture is None


def test_wrist_1_points_the_hand_camera_at_the_look_ahead_point():
    """The camera axis (the hand frame's x) passes within a few cm of the point `lookahead_m` ahead at
    `lookahead_height_m`: the ready pose alone looks 23° down, over where a vacated place would be seen through."""
    robot, params = RobotModel(), SequencerParams()
    hand = ReadyHand.of(robot)
    assert np.degrees(hand.pitch_rad) < -20 and abs(hand.pitch_per_wrist_1 + 1.0) < 0.05
    refs = navigation_references(np.array([[0.0, 0.0], [6.0, 0.0]]), 0.0, 0.0, None, hand, params, 10, 0.1,
                                 ("base", "ee"), False)
    assert refs.posture is not None
    T = robot.frame_poses(np.concatenate([[0.0, 0.0, 0.0], refs.posture[0]]), ("ee",))["ee"]
    eye, axis = T[:3, 3], T[:3, 0]
    hit = eye + axis * (params.lookahead_height_m - eye[2]) / axis[2]  # where the axis meets that height
    look_x = params.lookahead_m  # the path runs along x from the base
    assert np.degrees(np.arctan2(axis[2], np.hypot(axis[0], axis[1]))) < -35
    assert abs(hit[0] - look_x) < 0.15 and abs(hit[1]) < 0.2
