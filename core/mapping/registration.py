"""Relative motion of a known object by registration, so a pushed box keeps its id.

The observed segment (world) is aligned to the object's submap surface (world, at the current pose) by
point-to-plane ICP solved directly for the motion a box on the floor (or on another box) can make:
translation in x, y, z and yaw about the vertical through the segment's centroid (4 DOF, Gauss-Newton).
Target normals come from the submap itself. Single-threaded numpy and scipy's k-d tree on purpose: the same
inputs give the same bits, which lockstep runs depend on (open3d's ICP, used before, summed in an order that
varied from call to call, and a 6-DOF result projected to the plane could slide a static box along itself).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree  # pyright: ignore[reportAttributeAccessIssue]  (compiled re-export)

MIN_POINTS = 20
"""Clouds smaller than this are not aligned (identity, fitness 0): too few points to tell a push from noise."""
STEP_TOL = 1e-5
"""ICP stops when an iteration moves the segment by less than this (m, and rad of yaw)."""


@dataclass(frozen=True)
class Alignment:
    """T (4×4) moving the observation onto the submap, the fraction of observed points with a
    correspondence, and the RMSE of those correspondences (m)."""

    T: np.ndarray
    fitness: float
    rmse_m: float


def surface_normals(points: np.ndarray, tree: cKDTree, neighbours: int) -> np.ndarray:
    """Unit normal (N×3) of each point: the least-variance direction of its `neighbours` nearest points."""
    k = min(neighbours, len(points))
    _, idx = tree.query(points, k=k)
    local = points[idx] - points[idx].mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    return vectors[:, :, 0]


def _yaw_about(yaw: float, centre: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """4×4: rotate by `yaw` about the vertical through `centre`, then translate by `shift`."""
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = centre - T[:3, :3] @ centre + shift
    return T


def align(source: np.ndarray, target: np.ndarray, max_correspondence_m: float, max_iterations: int,
          normal_neighbours: int) -> Alignment:
    """Point-to-plane ICP of `source` (N×3) onto `target` (M×3), from the identity, over x, y, z and yaw;
    target normals from each point's `normal_neighbours` nearest."""
    source, target = np.asarray(source, dtype=float), np.asarray(target, dtype=float)
    if min(len(source), len(target)) < MIN_POINTS:
        return Alignment(T=np.eye(4), fitness=0.0, rmse_m=math.inf)
    tree = cKDTree(target)
    normals = surface_normals(target, tree, normal_neighbours)
    T = np.eye(4)
    for _ in range(max_iterations):
        moved = source @ T[:3, :3].T + T[:3, 3]
        dist, idx = tree.query(moved, distance_upper_bound=max_correspondence_m)
        ok = np.isfinite(dist)
        if ok.sum() < MIN_POINTS:
            break
        p, n = moved[ok], normals[idx[ok]]
        residual = np.einsum("ij,ij->i", n, p - target[idx[ok]])
        centre = p.mean(axis=0)
        arm = p - centre
        J = np.c_[n, n[:, 1] * arm[:, 0] - n[:, 0] * arm[:, 1]]
        delta = np.linalg.solve(J.T @ J + 1e-9 * np.eye(4), -J.T @ residual)
        T = _yaw_about(float(delta[3]), centre, delta[:3]) @ T
        if np.linalg.norm(delta[:3]) < STEP_TOL and abs(delta[3]) < STEP_TOL:
            break
    return _score(source, target, tree, T, max_correspondence_m)


def _score(source: np.ndarray, target: np.ndarray, tree: cKDTree, T: np.ndarray,
           max_correspondence_m: float) -> Alignment:
    """The alignment T with its fitness and inlier RMSE against the target."""
    dist, _ = tree.query(source @ T[:3, :3].T + T[:3, 3], distance_upper_bound=max_correspondence_m)
    inlier = np.isfinite(dist)
    rmse = float(np.sqrt(np.mean(dist[inlier] ** 2))) if np.any(inlier) else math.inf
    return Alignment(T=T, fitness=float(np.mean(inlier)), rmse_m=rmse)
