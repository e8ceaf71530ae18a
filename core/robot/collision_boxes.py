"""The base's collision boxes: the Ridgeback body and the rack on it. One table, read by the MuJoCo model
(`core/sim/world_spec.py`), the controller (exact box barriers, `core/htmpc/box_barrier.py`), the
mapping self-filter and the studio, so the geometry the controller keeps clear is the one that collides.

Spheres cannot cover a flat box tightly: every cover of the 0.96 × 0.79 × 0.24 m body by spheres
reaches at least 8.5 cm beyond some face (the corner spheres), and the paper's single 0.55 m sphere
left the corners 9.4 cm out. The controller uses the boxes themselves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.params import RobotParams


@dataclass(frozen=True)
class CollisionBox:
    """A box of half sides `half_m` centred at `centre_m` in the base frame (`mobile_base`, after the yaw)."""

    name: str
    centre_m: tuple[float, float, float]
    half_m: tuple[float, float, float]

    @property
    def lo(self) -> np.ndarray:
        return np.subtract(self.centre_m, self.half_m)

    @property
    def hi(self) -> np.ndarray:
        return np.add(self.centre_m, self.half_m)


def base_boxes(params: RobotParams) -> tuple[CollisionBox, ...]:
    """The body (from `base_clearance_m` up to the top plate) and the rack standing on the plate."""
    lx, ly, lz = params.base_size_m
    floor = params.base_clearance_m
    rx, ry, rz = params.rack_size_m
    return (CollisionBox("base_body", (0.0, 0.0, (lz + floor) / 2), (lx / 2, ly / 2, (lz - floor) / 2)),
            CollisionBox("base_rack", (params.rack_x_m, 0.0, lz + rz / 2), (rx / 2, ry / 2, rz / 2)))
