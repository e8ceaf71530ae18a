"""While the base drives the arm holds its ready joints, the pan turned toward the path ahead within its limit."""

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
    np.testing.assert_allclose(refs.posture, np.tile(READY_Q[3:], (11, 1)), atol=1e-9)  # straight: the ready pose
    turn = navigation_references(left_turn, 0.0, 0.0, None, hand, params, 10, 0.1, ("ee", "base"), False)
    assert turn.order == ("posture", "base") and turn.posture is not None
    pan = turn.posture[:, 0]
    assert pan[0] > np.radians(30)  # looks left, into the turn
    assert np.all(np.abs(pan) <= np.radians(params.lookahead_turn_max_deg) + 1e-9)
    held = navigation_references(straight, 0.0, 0.0, None, hand, params, 10, 0.1, ("base", "ee"), False,
                                 ee_hold=(np.array([0.6, 0.0, 1.0]), None))
    assert held.order == ("base", "ee") and held.ee is not None and held.posture is None
