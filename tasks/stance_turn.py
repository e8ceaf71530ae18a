"""Turning into the stance before the hand reaches: what an EE subtask asks while the base's heading is far from its
stance's (`manipulation_stance`: the base faces the target).

With the hand's task first ([J_EE, J_base], the paper's manipulation order) a base that starts side-on to a target
beside it drives the shoulder toward the target side-on: once its side is at delta_safe from the obstacle under the
target, turning to face the target would sweep its corners (0.62 m from the centre against a 0.395 m half width)
into that clearance, and the hand's bound (7c) holds the base there. The arm then reaches at full stretch (elbow
0.02 rad on the aisle's picks) and a few centimetres of map or pose error leave the hand short: measured on
`tasks/examples/aisle_laps.yaml` with the drift and localization on, lap 3's pick at stop B stopped 3.0 cm from
its goal (tolerance 3 cm) with the island mapped 5.5 cm toward the aisle. Turned first (the base's task leading),
the same recorded pick ends 0.3 cm off with the arm relaxed (elbow 0.84 rad), and still 0.3 cm off with the island
mapped 3 cm closer again. While it turns the arm holds its ready joints (docs/decisions.md, "The aisle laps with the
drift and localization on").
"""

from __future__ import annotations

import math

import numpy as np

from core.angles import wrap_angle
from core.robot.model import READY_Q
from core.types import BaseReference, References


def heading_gap(base_yaw: float, stance_yaw: float) -> float:
    """|base_yaw − stance_yaw| wrapped to [0, π] (rad)."""
    return abs(wrap_angle(base_yaw - stance_yaw))


def needs_turn(base_yaw: float, stance_yaw: float, turn_deg: float) -> bool:
    """Whether the base is farther than `turn_deg` (deg) from its stance's heading."""
    return heading_gap(base_yaw, stance_yaw) > math.radians(turn_deg)


def turn_references(stance: np.ndarray, switched: bool) -> References:
    """While the base turns into its stance (x, y, yaw): the base's task first, the arm holding its ready joints as
    it does while the base drives (measured on the aisle, seed 1: reaching during the spin, the hand camera saw the
    base's own front, and the map kept it as a 0.57 m object in the aisle that blocked the next lap)."""
    base = BaseReference(xy=np.asarray(stance[:2], float)[None], yaw=np.array([float(stance[2])]))
    ready = np.asarray(READY_Q[3:], float)[None]
    return References(order=("base", "posture"), base=base, switched=switched, posture=ready)
