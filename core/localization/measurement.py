"""A registration read as a measurement of the base pose: its gates (convergence, inliers), the directions its
points constrain (`degeneracy.py`), and the base pose it puts the frame at. The map's registrations
(`localizer.py`) and the loop closures onto keyframes (`loop_closure.py`) read theirs alike."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.localization import degeneracy, gates, registration, se2
from core.localization.gates import Verdict
from core.params import LocalizationParams
from core.types import DepthFrame


@dataclass(frozen=True)
class Measurement:
    """The base pose (x, y, yaw) a registration measures and the directions it constrains."""

    pose: np.ndarray
    directions: degeneracy.Directions


def measure(result: registration.Result, frame: DepthFrame, base_pose: np.ndarray, source_points: np.ndarray,
            p: LocalizationParams) -> Verdict | Measurement:
    """The verdict of a registration that fails its gates (not converged, too few points or inliers, no direction
    constrained), else the base pose it measures: the frame's correction T_world←camera · T_frame⁻¹ applied to
    `base_pose` (the base at the frame's exposure), with the directions its `source_points` (N×3) constrain."""
    failure = gates.registration_verdict(result.converged, result.inliers, result.source_points, p)
    if failure is not None:
        return failure
    T = result.T_world_camera
    lever = degeneracy.rms_lever(source_points, T, base_pose[:2])
    dirs = degeneracy.directions(result.H, T, base_pose[:2], result.inliers, lever, p.degenerate_information)
    if dirs.dof == 0:
        return Verdict.DEGENERATE
    return Measurement(se2.compose(se2.from_matrix(T @ np.linalg.inv(frame.T_world_camera)), base_pose), dirs)
