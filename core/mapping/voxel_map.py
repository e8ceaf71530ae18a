"""Voxel-level baseline map (the paper's comparison): a static-world occupancy grid with carving.

OctoMap-style log-odds per 5 cm voxel (hit +0.85, miss −0.4, clamped to [−2, 3.5], occupied above 0),
stored sparsely (sorted packed keys). Each depth frame adds its non-floor, non-robot points as hits
(voxels in clusters smaller than `min_segment_voxels` are speckle and ignored, as in the object map),
and carves free space projectively, as a TSDF integrator does: every mapped voxel is projected into
the frame and counts a miss when the depth measured through its pixel lies beyond it (or nothing
returned within range). This is ray casting evaluated per voxel, and it only ever touches voxels the
rays reach: a voxel that no ray passes through stays as it was.

So a box moved while unseen stays a phantom until every voxel of it is re-seen as free, and a
box seen for long needs several clear frames per voxel (from the clamp, ceil(3.5 / 0.4) + 1 = 10
misses) to fade, voxel by voxel; the object-level map drops the whole object at once.
"""

from __future__ import annotations

import time

import numpy as np

from core.mapping.local_edf import EDFGrid, local_edf, mark_points
from core.mapping.scene_points import ScenePoints, latest_time
from core.mapping.segmentation import speckle_free, voxelise
from core.mapping.submap import pack, unpack
from core.mapping.visibility import THROUGH, FrameView
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import DepthFrame, LocalEDF, ObjectMapSnapshot, Observation


class VoxelMap:
    """Occupancy voxels with free-space carving, behind the `WorldMap` interface."""

    def __init__(self, robot: RobotModel, params: MappingParams | None = None) -> None:
        self.robot = robot
        self.params = params or MappingParams()
        self.scene_points = ScenePoints(robot, self.params)
        self.keys = np.zeros(0, dtype=np.int64)
        self.logodds = np.zeros(0, dtype=np.float32)
        self.timings_ms: dict[str, float] = {"points": 0.0, "integration": 0.0, "carving": 0.0, "edf": 0.0}
        self._t = 0.0

    # --- WorldMap ---------------------------------------------------------------------------------

    def integrate(self, obs: Observation) -> None:
        timings = {"points": 0.0, "integration": 0.0, "carving": 0.0, "edf": self.timings_ms.get("edf", 0.0)}
        for frame, points in self.scene_points.each(obs, timings):
            self._integrate_frame(frame, points, timings)
        self._t = latest_time(self._t, obs)
        self.timings_ms = timings

    def snapshot(self) -> ObjectMapSnapshot:
        return ObjectMapSnapshot(t=self._t, objects=(), removed_ids=())

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        """Signed EDF (9a–9b) of the occupied voxels in the window around `centre_xy`."""
        t0 = time.perf_counter()
        p = self.params
        grid = EDFGrid.around(np.asarray(centre_xy, dtype=float), p.edf_window_m, p.edf_voxel_m, 0.5)
        occupied = grid.empty()
        mark_points(grid, occupied, self.occupied_points())
        edf = local_edf(grid, occupied, p.theta_cutoff_m)
        self.timings_ms["edf"] = (time.perf_counter() - t0) * 1e3
        return edf

    def occupied_points(self) -> np.ndarray:
        """Centres (P×3) of the voxels with log-odds above 0."""
        return self.centres(self.keys[self.logodds > 0.0])

    # --- internals --------------------------------------------------------------------------------

    def centres(self, keys: np.ndarray) -> np.ndarray:
        return (unpack(keys).astype(float) + 0.5) * self.params.voxel_m

    def _integrate_frame(self, frame: DepthFrame, points: np.ndarray, timings: dict[str, float]) -> None:
        p = self.params
        t0 = time.perf_counter()
        hit_keys = np.unique(pack(speckle_free(voxelise(points, p.voxel_m), p.min_segment_voxels)))
        self._carve(frame, hit_keys)
        t1 = time.perf_counter()
        self._add_hits(hit_keys)
        timings["carving"] += (t1 - t0) * 1e3
        timings["integration"] += (time.perf_counter() - t1) * 1e3

    def _carve(self, frame: DepthFrame, hit_keys: np.ndarray) -> None:
        """Misses for the mapped voxels seen through in this frame (not those hit in it)."""
        if len(self.keys) == 0:
            return
        p = self.params
        view = FrameView.of(frame, p)
        through = view.classify(self.centres(self.keys)) == THROUGH
        through &= ~np.isin(self.keys, hit_keys, assume_unique=True)
        self.logodds[through] = np.maximum(self.logodds[through] + p.logodds_miss, p.logodds_min)
        keep = self.logodds > p.logodds_min
        self.keys, self.logodds = self.keys[keep], self.logodds[keep]

    def _add_hits(self, hit_keys: np.ndarray) -> None:
        p = self.params
        pos = np.searchsorted(self.keys, hit_keys)
        found = pos < len(self.keys)
        found[found] = self.keys[pos[found]] == hit_keys[found]
        idx = pos[found]
        self.logodds[idx] = np.minimum(self.logodds[idx] + p.logodds_hit, p.logodds_max)
        new = hit_keys[~found]
        if len(new):
            keys = np.concatenate([self.keys, new])
            order = np.argsort(keys, kind="stable")
            self.keys = keys[order]
            self.logodds = np.concatenate([self.logodds, np.full(len(new), p.logodds_hit, dtype=np.float32)])[order]
