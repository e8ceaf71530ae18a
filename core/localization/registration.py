"""Scan-to-map registration with small_gicp's GICP (the field's library; measured against open3d and
kiss-icp in docs/decisions.md, "Localization"): a frame's points against the reference, from the predicted
camera pose, within a correspondence radius; one thread, deterministic."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import small_gicp  # pyright: ignore[reportMissingImports]  (a compiled module without stubs)

NEIGHBOURS = 10
"""Points whose spread gives each point's covariance (GICP's local plane)."""
SIDE_NZ = 0.5
"""A reference point whose normal's vertical part is below this lies on a side face (its normal within 60° of
horizontal): only those faces pin the base's x, y and yaw."""


@dataclass(frozen=True)
class Result:
    """T_world_camera after registration, small_gicp's H (6×6; rx, ry, rz, tx, ty, tz on T·exp(δ)), its
    inlier count, the frame's point count after thinning, and whether it converged."""

    T_world_camera: np.ndarray
    H: np.ndarray
    inliers: int
    source_points: int
    converged: bool
    ms: float


class Target:
    """The reference prepared for registration (covariances, k-d tree), kept until the reference changes;
    point i is reference point i (no thinning), so residuals map back to objects."""

    def __init__(self, points: np.ndarray) -> None:
        t0 = time.perf_counter()
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.cloud = small_gicp.PointCloud(self.points)
        self.tree = small_gicp.KdTree(self.cloud, num_threads=1)
        small_gicp.estimate_covariances(self.cloud, self.tree, num_neighbors=NEIGHBOURS, num_threads=1)
        self._covariances: np.ndarray | None = None
        """The covariances' 3×3 blocks, read on the first `side_offsets`."""
        self.ms = (time.perf_counter() - t0) * 1e3

    def nearest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index of the nearest reference point of each point and the distance to it (m)."""
        idx, sq = self.tree.batch_nearest_neighbor_search(np.ascontiguousarray(points, np.float64), num_threads=1)
        return np.asarray(idx, int).reshape(-1), np.sqrt(np.asarray(sq, float).reshape(-1))

    def side_offsets(self, points: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For points (world) and the index of their nearest reference point (≥ 0): the distance (m) of each from
        that point's local plane (the least-spread direction of its GICP covariance), and whether that plane is a
        side face (`SIDE_NZ`). Off a plane, not off a sample: a point of a face sampled 5 cm apart lies up to 3.5 cm
        from the nearest sample, and the face's part not yet mapped lies farther still, in its plane."""
        if self._covariances is None:
            self._covariances = np.asarray(self.cloud.covs())[:, :3, :3]
        _, vectors = np.linalg.eigh(self._covariances[idx])
        normal = vectors[:, :, 0]
        offset = np.einsum("ij,ij->i", normal, np.asarray(points, float) - self.points[idx])
        return np.abs(offset), np.abs(normal[:, 2]) < SIDE_NZ


def thin(points_camera: np.ndarray, voxel_m: float) -> tuple[small_gicp.PointCloud, int]:
    """The frame's points (camera frame) thinned to a voxel grid, with covariances."""
    cloud, _ = small_gicp.preprocess_points(np.ascontiguousarray(points_camera, np.float64),
                                            downsampling_resolution=voxel_m, num_neighbors=NEIGHBOURS, num_threads=1)
    return cloud, int(cloud.size())


def register(target: Target, source: small_gicp.PointCloud, T_init: np.ndarray, radius_m: float,
             max_iterations: int) -> Result:
    """GICP of the source (camera frame) onto the target (world) from T_init = the predicted T_world_camera."""
    t0 = time.perf_counter()
    r = small_gicp.align(target.cloud, source, target.tree, init_T_target_source=T_init, registration_type="GICP",
                         max_correspondence_distance=radius_m, num_threads=1, max_iterations=max_iterations)
    ms = (time.perf_counter() - t0) * 1e3
    return Result(np.asarray(r.T_target_source), np.asarray(r.H), int(r.num_inliers), int(source.size()),
                  bool(r.converged), ms)
