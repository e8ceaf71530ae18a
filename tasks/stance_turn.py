"""Turning into the stance before the hand reaches: the priority order of an EE subtask while the base's heading is
far from its stance's (`manipulation_stance`: the base faces the target).

With the hand's task first ([J_EE, J_base], the paper's manipulation order) a base that starts side-on to a target
beside it drives the shoulder toward the target side-on: once its side is at delta_safe from the obstacle under the
target, turning to face the target would sweep its corners (0.62 m from the centre against a 0.395 m half width)
into that clearance, and the hand's bound (7c) holds the base there. The arm then reaches at full stretch (elbow
0.02 rad on the aisle's picks) and a few centimetres of map or pose error leave the hand short: measured on
`tasks/examples/aisle_laps.yaml` with the drift and localization on, lap 3's pick at stop B stopped 3.0 cm from
its goal (tolerance 3 cm) with the island mapped 5.5 cm toward the aisle. Turned first, the same recorded pick ends
0.3 cm off with the arm relaxed (elbow 0.84 rad), and still 0.3 cm off with the island mapped 3 cm closer again
(docs/decisions.md, "The aisle laps with the drift and localization on").
"""

from __future__ import annotations

import math


def heading_gap(base_yaw: float, stance_yaw: float) -> float:
    """|base_yaw − stance_yaw| wrapped to [0, π] (rad)."""
    return abs((base_yaw - stance_yaw + math.pi) % (2 * math.pi) - math.pi)


def needs_turn(base_yaw: float, stance_yaw: float, turn_deg: float) -> bool:
    """Whether the base is farther than `turn_deg` (deg) from its stance's heading."""
    return heading_gap(base_yaw, stance_yaw) > math.radians(turn_deg)


def turn_first(order: tuple[str, ...]) -> tuple[str, ...]:
    """The subtask's order with the base's task first (the hand's follows it): the base turns into its stance."""
    return ("base", *(name for name in order if name != "base"))
