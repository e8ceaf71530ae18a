"""Telling the operator why the base slows or stops: unknown space ahead (docs/method.md, "Unknown space is not
free"). The map hands unknown space to the controller inside its `LocalEDF` (as obstacles) and attaches the
`UnknownSpace` itself; here the closed loop reads it to say so in the status line and the Problems panel, and
to give the planner the unknown columns as occupied.

A control step counts as slowed by unknown space when the base reference leads toward the nearest unknown
column and that column lies inside the CBF's slowing zone: its clearance from the base's front, less
delta_safe, below v_max / gamma (beyond that, dh/dt ≥ −gamma h allows the base's full speed toward it).
"""

from __future__ import annotations

import numpy as np

from core.types import LocalEDF, References, RobotState

PROBE_Z_M = 0.2
"""Height at which the base's distance to unknown space is measured (within the base's body)."""


def planner_points(occupied: np.ndarray, edf: LocalEDF | None) -> np.ndarray:
    """The map's occupied points with the unknown columns' centres (at half their height) for the planner."""
    space = edf.unknown if edf is not None else None
    if space is None or len(space.centres) == 0:
        return occupied
    return np.vstack([occupied.reshape(-1, 3), space.points(space.height_m / 2)])


def unknown_ahead(state: RobotState, refs: References | None, edf: LocalEDF | None, half_length_m: float,
                  delta_safe_m: float, slowing_zone_m: float) -> str | None:
    """The operator's notice when unknown space slows the base now (see the module), else None."""
    space = edf.unknown if edf is not None else None
    if space is None or len(space.centres) == 0 or refs is None or refs.base is None:
        return None
    base = np.array([state.q[0], state.q[1], PROBE_Z_M])
    distance, nearest = space.distance(base)
    clearance = float(distance) - half_length_m
    if clearance - delta_safe_m > slowing_zone_m:
        return None
    heading = np.asarray(refs.base.xy[-1], float) - base[:2]
    if float(np.dot(heading, nearest[:2] - base[:2])) <= 0.0:
        return None  # behind or beside the way the base is sent
    return (f"unknown space ahead: no depth returned from {max(clearance, 0.0):.2f} m ahead of the base "
            "(a surface the cameras cannot see?); slowing, and stopping before it")
