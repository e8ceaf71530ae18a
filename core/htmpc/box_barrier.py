"""Exact barriers for the base's collision boxes (body and rack): per node, the point of each box closest to
the obstacles, as a body-fixed point of radius 0 for the collision rows (eq. 10).

h_box = min over the box of EDF − delta_safe. The minimiser p* is found by alternating projections between
the box and the obstacles: the EDF projects a point onto the nearest obstacle surface (o = p − EDF(p) ∇EDF),
the box projects back by clamping in the base frame. For convex obstacles this converges to the closest
pair. Several seeds per box (the centres of its four side faces) keep one row per side, so a corridor's
two walls are both constrained. The gradient of h in q is that of the fixed body point p* (the min's
envelope), so the rows take p* with its Jacobian like a sphere centre.

Why not spheres: any sphere cover of the 0.96 × 0.79 × 0.24 m body reaches ≥ 8.5 cm beyond some face,
and at 1 m/s the base brakes in 0.25 m: a cover that wide costs a third of the braking distance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.htmpc.distance_field import DistanceField, distance_and_gradient
from core.robot.collision_boxes import CollisionBox

SIDES = ("front", "back", "left", "right")
SIDE_SEEDS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
"""A row per side of each box, in the base frame: its seeds are the side's face centre and its two corners."""
CORNER_SEEDS = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
SIDE_CORNERS = ((0, 1), (2, 3), (0, 2), (1, 3))
"""The corners (indices into CORNER_SEEDS) on each side of SIDE_SEEDS."""
FLAT_GRADIENT = 0.1
"""Where |∇EDF| is below this (beyond the field's cutoff) the EDF names no obstacle: the point stays put."""


@dataclass(frozen=True)
class BoxPoints:
    """Body-fixed points (K nodes, R rows): world positions P (K,R,3), ∂P/∂q (K,R,3,9) and ∂(J_P v)/∂q."""

    P: np.ndarray
    JP: np.ndarray
    dvel_dq: np.ndarray
    distance: np.ndarray | None = None
    """EDF at P (K,R) and its gradient (K,R,3), from the lookup that chose the points (no second lookup)."""
    gradient: np.ndarray | None = None
    also: tuple[np.ndarray, np.ndarray] | None = None
    """EDF value and gradient at the extra points `points(..., also=)` asked for, from the same batch of
    queries (the collision spheres: one EDF lookup fewer per SQP iteration)."""


class BoxBarrier:
    """Closest points of the base's boxes to the obstacles: a row per side of each box (front, back, left,
    right), the best of three seeds (the side's face centre and its two vertical edges, at mid height) after
    `iterations` alternating projections. A seed converges to the obstacle nearest to it, which need not be
    the box's nearest (a box overhead beside one on the floor at a corner): more seeds, fewer misses."""

    def __init__(self, boxes: tuple[CollisionBox, ...], iterations: int = 3) -> None:
        self.names = [f"{b.name}_{side}" for b in boxes for side in SIDES]
        units = np.vstack([SIDE_SEEDS, CORNER_SEEDS])
        n = len(units)
        self.lo = np.repeat([b.lo for b in boxes], n, axis=0)
        self.hi = np.repeat([b.hi for b in boxes], n, axis=0)
        centre, half = (self.lo + self.hi) / 2, (self.hi - self.lo) / 2
        self.seeds = centre + np.column_stack([np.tile(units, (len(boxes), 1)) * half[:, :2], np.zeros(len(centre))])
        per_side = [[k, len(SIDE_SEEDS) + a, len(SIDE_SEEDS) + b] for k, (a, b) in enumerate(SIDE_CORNERS)]
        self.groups = np.array([[i * n + j for j in seeds] for i in range(len(boxes)) for seeds in per_side])
        """Seed indices (rows, 3) each row chooses from."""
        self.iterations = iterations

    @property
    def n_rows(self) -> int:
        return len(self.groups)

    def local_points(self, q: np.ndarray, edf: DistanceField) -> np.ndarray:
        """Base-frame closest points (K, rows, 3) of each row's box to the obstacles, at base poses q[:, :3]."""
        return self._closest(q, edf)[0]

    def _closest(self, q: np.ndarray, edf: DistanceField, also: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
        """`local_points` with the EDF's value (K, rows) and gradient (K, rows, 3) there, and the EDF's value and
        gradient at the points `also` (K, A, 3) (None if not given), queried with the first batch."""
        turn = _yaw_matrices(q[:, 2])  # row vectors: world offset = local @ turn
        origin = np.column_stack([q[:, 0], q[:, 1], np.zeros(len(q))])[:, None]
        local = np.broadcast_to(self.seeds, (len(q), *self.seeds.shape))
        extra = None

        def lookup(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            nonlocal extra
            if also is None or extra is not None:
                return distance_and_gradient(edf, p)
            d, g = distance_and_gradient(edf, np.concatenate([also, p], axis=1))
            n = also.shape[1]
            extra = (d[:, :n], g[:, :n])
            return d[:, n:], g[:, n:]

        for _ in range(self.iterations):
            p = origin + local @ turn
            d, g = lookup(p)
            norm = np.linalg.norm(g, axis=-1)
            ok = (norm > FLAT_GRADIENT) & np.isfinite(d)  # a broken map moves no point (its rows fail the QP)
            step = np.where(ok, d / np.where(ok, norm, 1.0), 0.0)[..., None] * np.where(ok[..., None], g, 0.0)
            local = np.clip((p - step - origin) @ np.swapaxes(turn, 1, 2), self.lo, self.hi)
        d, g = lookup(origin + local @ turn)
        best = np.take_along_axis(self.groups[None], np.argmin(d[:, self.groups], axis=2)[..., None], axis=2)[..., 0]
        return (np.take_along_axis(local, best[..., None], axis=1), np.take_along_axis(d, best, axis=1),
                np.take_along_axis(g, best[..., None], axis=1), extra)

    def points(self, q: np.ndarray, v: np.ndarray, edf: DistanceField, also: np.ndarray | None = None) -> BoxPoints:
        """The rows' points at nodes q (K, 9) with velocities v (K, 9): world positions, Jacobians, and the EDF
        there (and at the points `also` (K, A, 3), see `BoxPoints.also`)."""
        local, distance, gradient, at_also = self._closest(q, edf, also)
        turned = local @ _yaw_matrices(q[:, 2])  # R(yaw) p_local
        K, R = local.shape[:2]
        P = turned + np.column_stack([q[:, 0], q[:, 1], np.zeros(K)])[:, None]
        JP = np.zeros((K, R, 3, 9))
        JP[:, :, 0, 0] = 1.0
        JP[:, :, 1, 1] = 1.0
        JP[:, :, 0, 2] = -turned[..., 1]  # ∂(R p)/∂yaw = [−(R p)_y, (R p)_x, 0]
        JP[:, :, 1, 2] = turned[..., 0]
        dvel = np.zeros((K, R, 3, 9))
        dvel[:, :, 0, 2] = -v[:, 2:3] * turned[..., 0]  # ∂/∂yaw of yaw_rate · ∂(R p)/∂yaw = −yaw_rate (R p)_xy
        dvel[:, :, 1, 2] = -v[:, 2:3] * turned[..., 1]
        return BoxPoints(P, JP, dvel, distance, gradient, at_also)


def _yaw_matrices(yaw: np.ndarray) -> np.ndarray:
    """R(yaw)^T per node (K, 3, 3): a row vector p turns into the world as p @ R^T."""
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.zeros((len(yaw), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1], out[:, 2, 2] = c, s, -s, c, 1.0
    return out
