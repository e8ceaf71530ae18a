"""The simulator's exact scene behind the same map interface as the perceived maps (the paper's
"ground-truth map" runs): no perception, the EDF computed from the true boxes."""

from __future__ import annotations

import numpy as np

from core.params import MappingParams
from core.sim.ground_truth import ground_truth_edf
from core.sim.world import SimWorld
from core.types import LocalEDF, ObjectMapSnapshot, Observation


class GroundTruthMap:
    """Reads boxes straight from the `SimWorld`; `integrate` only notes the time."""

    def __init__(self, world: SimWorld, params: MappingParams | None = None, surface_step_m: float = 0.1) -> None:
        self.world = world
        self.params = params or MappingParams()
        self.surface_step_m = surface_step_m
        self.timings_ms: dict[str, float] = {}
        self._t = 0.0

    def integrate(self, obs: Observation) -> None:
        self._t = obs.state.t

    def snapshot(self) -> ObjectMapSnapshot:
        return ObjectMapSnapshot(t=self._t, objects=())

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        p = self.params
        return ground_truth_edf(self.world.obstacles(), centre_xy, p.edf_window_m, p.edf_voxel_m, p.theta_cutoff_m)

    def occupied_points(self) -> np.ndarray:
        """Points on a grid inside every box (for path planning and display)."""
        pts = []
        step = self.surface_step_m
        for box in self.world.obstacles():
            axes = [np.arange(-s / 2 + step / 2, s / 2, step) if s > step else np.zeros(1) for s in box.size]
            local = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            T = box.pose()
            pts.append(local @ T[:3, :3].T + T[:3, 3])
        return np.concatenate(pts) if pts else np.zeros((0, 3))
