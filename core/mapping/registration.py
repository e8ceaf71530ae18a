"""Relative motion of a known object by registration (open3d ICP), so a pushed box keeps its id.

The observed segment (world) is aligned to the object's submap surface (world, at the current pose)
by point-to-plane ICP; target normals come from the submap itself. Boxes stand on the floor or on
each other, so the result is projected to a planar motion: translation in x, y, z and yaw only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import open3d as o3d

_REG = o3d.pipelines.registration


@dataclass(frozen=True)
class Alignment:
    """T (4×4) moving the observation onto the submap, the fraction of observed points with a
    correspondence, and the RMSE of those correspondences (m)."""

    T: np.ndarray
    fitness: float
    rmse_m: float


def planar(T: np.ndarray) -> np.ndarray:
    """The nearest motion of translation plus yaw (rotation about world z) to a rigid transform."""
    yaw = math.atan2(T[1, 0] - T[0, 1], T[0, 0] + T[1, 1])
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:3, 3] = T[:3, 3]
    return out


def _cloud(points: np.ndarray) -> o3d.geometry.PointCloud:
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=float)))


def align(source: np.ndarray, target: np.ndarray, max_correspondence_m: float, max_iterations: int,
          normal_radius_m: float) -> Alignment:
    """Point-to-plane ICP of `source` (N×3) onto `target` (M×3), from the identity, made planar."""
    src, dst = _cloud(source), _cloud(target)
    dst.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=normal_radius_m, max_nn=16))
    result = _REG.registration_icp(
        src, dst, max_correspondence_m, np.eye(4), _REG.TransformationEstimationPointToPlane(),
        _REG.ICPConvergenceCriteria(max_iteration=max_iterations))
    T = planar(np.asarray(result.transformation))
    check = _REG.evaluate_registration(src, dst, max_correspondence_m, T)
    return Alignment(T=T, fitness=float(check.fitness), rmse_m=float(check.inlier_rmse))
