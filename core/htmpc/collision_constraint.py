"""Collision avoidance from a distance field (eq. 10): one row per collision sphere and node.

h_j(x) = EDF(P_j(q)) − r_j − delta_safe, linearised at the current iterate q̄ with the EDF's value and
gradient at the predicted sphere centres: h ≈ h̄ + g^T (q − q̄), g = J_Pj(q̄)^T ∇EDF(P̄_j).
- EDF baseline:  h ≥ 0                      →  g^T q + s ≥ g^T q̄ − h̄
- CBF (proposed): dh/dt ≥ −gamma h with dh/dt = ∇EDF^T J_P(q) v linearised at (q̄, v̄):
  dh/dt ≈ g^T v + c^T (q − q̄), c = ∂(J_P(q) v̄)/∂q^T ∇EDF (the sphere velocity turns with the arm)
  →  g^T v + (gamma g + c)^T q + s ≥ (gamma g + c)^T q̄ − gamma h̄
The slack s ≥ 0 (penalised in the cost) keeps the problem feasible when a box appears suddenly.
The base's boxes add rows of the same form at their points closest to the obstacles, radius 0
(`box_barrier.py`), after the spheres' rows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core.htmpc.distance_field import DistanceField, distance_and_gradient
from core.htmpc.horizon_kinematics import HorizonKinematics

if TYPE_CHECKING:
    from core.htmpc.box_barrier import BoxBarrier

__all__ = ["CollisionConstraint", "CollisionRows", "DistanceField", "StepRows", "step_rows"]


@dataclass(frozen=True)
class CollisionRows:
    """Rows a_q·q_k + a_v·v_k + s ≥ lb for nodes 1..K−1 (first axis) and spheres (second axis)."""

    a_q: np.ndarray
    a_v: np.ndarray
    lb: np.ndarray
    h: np.ndarray
    """h̄ per node and sphere (m), for diagnostics."""


@dataclass(frozen=True)
class StepRows:
    """The collision rows at τ into the first interval (the next control instant), in that interval's
    acceleration: a_a · a_0 + s_0 ≥ lb, from q(τ) = q_0 + τ v_0 + ½ τ² a_0 and v(τ) = v_0 + τ a_0.

    The rows at the nodes alone let a plan brake gently inside the first 0.3 s interval and still meet them
    (at node 1 the plan may already move away again, and a CBF row admits h < 0 while h grows); the robot
    executes only that interval's first control period and re-plans, so braking by such plans stops late
    (docs/decisions.md, "Collision rows at the next control instant"). These rows hold the executed motion
    itself to the constraint."""

    a_a: np.ndarray
    lb: np.ndarray
    h: np.ndarray


def step_rows(rows: CollisionRows, q0: np.ndarray, v0: np.ndarray, tau: float) -> StepRows:
    """`StepRows` from the collision rows of one node at τ (the first entry of `rows`) and the state (q0, v0)."""
    a_q, a_v = rows.a_q[0], rows.a_v[0]
    return StepRows(a_a=0.5 * tau**2 * a_q + tau * a_v, lb=rows.lb[0] - a_q @ (q0 + tau * v0) - a_v @ v0,
                    h=rows.h[0])


class CollisionConstraint:
    """Builds the linearised EDF or CBF rows (docs/method.md, eq. 10)."""

    def __init__(self, radii: np.ndarray, delta_safe_m: float, gamma: float, kind: str = "cbf",
                 boxes: BoxBarrier | None = None) -> None:
        if kind not in ("cbf", "edf"):
            raise ValueError(f"constraint kind must be 'cbf' or 'edf', got {kind!r}")
        self.boxes = boxes
        self.radii = np.concatenate([np.asarray(radii, float), np.zeros(boxes.n_rows if boxes else 0)])
        """Per row: the spheres' radii, then 0 for the box rows."""
        self.delta_safe_m = delta_safe_m
        self.gamma = gamma
        self.kind = kind

    def barrier(self, edf: DistanceField, centres: np.ndarray) -> np.ndarray:
        """h = EDF(P) − r − delta_safe for centres (..., M, 3)."""
        return edf.distance(centres) - self.radii - self.delta_safe_m

    @property
    def n_rows(self) -> int:
        """Rows per node: one per sphere and per box side."""
        return len(self.radii)

    def rows(self, q_bar: np.ndarray, kin: HorizonKinematics, edf: DistanceField,
             v_bar: np.ndarray | None = None) -> CollisionRows:
        """Rows for nodes 1..K−1 of the iterate q̄ (K, 9) with velocities v̄ (zero if None)."""
        dvel = kin.dvel_dq[1:] if kin.dvel_dq is not None else np.zeros_like(kin.JP[1:])
        v = np.zeros_like(q_bar) if v_bar is None else v_bar
        return self.rows_at(q_bar[1:], v[1:], kin.P[1:], kin.JP[1:], dvel, edf)

    def rows_at(self, q: np.ndarray, v: np.ndarray, P: np.ndarray, JP: np.ndarray, dvel: np.ndarray,
                edf: DistanceField) -> CollisionRows:
        """Rows at any K configurations q (K, 9) with velocities v, given their spheres' centres P (K, M, 3),
        Jacobians JP and ∂(J_P v)/∂q; the base boxes' rows are added here. One batch of EDF queries for all."""
        if self.boxes is not None:  # the spheres' EDF comes with the boxes' first batch of queries (`BoxPoints`)
            pts = self.boxes.points(q, v, edf, also=P)
            assert pts.also is not None and pts.distance is not None and pts.gradient is not None, "one batch"
            JP, dvel = np.concatenate([JP, pts.JP], axis=1), np.concatenate([dvel, pts.dvel_dq], axis=1)
            d, grad = np.concatenate([pts.also[0], pts.distance], axis=1), np.concatenate([pts.also[1], pts.gradient],
                                                                                         axis=1)
        else:
            d, grad = distance_and_gradient(edf, P)
        h = d - self.radii - self.delta_safe_m
        g = np.einsum("kmc,kmcj->kmj", grad, JP)
        gq = np.einsum("kmj,kj->km", g, q)
        if self.kind == "edf":
            return CollisionRows(a_q=g, a_v=np.zeros_like(g), lb=gq - h, h=h)
        c = np.einsum("kmc,kmcj->kmj", grad, dvel)
        a_q = self.gamma * g + c
        return CollisionRows(a_q=a_q, a_v=g, lb=np.einsum("kmj,kj->km", a_q, q) - self.gamma * h, h=h)
