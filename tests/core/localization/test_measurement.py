"""A registration read as a base-pose measurement (`core/localization/measurement.py`): its gates, the directions
it constrains, and the pose it puts the base at."""

import math

import numpy as np
import pytest

from core.localization import se2
from core.localization.gates import Verdict
from core.localization.measurement import Measurement, measure
from core.localization.registration import Result
from core.params import LocalizationParams
from core.types import DepthFrame
from tests.core.localization.synthetic import camera_pose

P = LocalizationParams()
POINTS = np.random.default_rng(0).uniform([-1.0, -0.5, 1.0], [1.0, 0.5, 3.0], (400, 3))
"""Points in the camera frame (z ahead), as a registration's source."""


def _frame(base: np.ndarray) -> DepthFrame:
    return DepthFrame(1.0, "base", np.zeros((4, 4)), np.eye(3), camera_pose(*base))


def _result(frame: DepthFrame, shift: np.ndarray, H: np.ndarray, converged: bool = True, inliers: int = 400
            ) -> Result:
    """`frame`'s camera moved by the world-frame planar motion `shift` (x, y, yaw about the world origin)."""
    return Result(se2.to_matrix(shift) @ frame.T_world_camera, H, inliers, len(POINTS), converged, 1.0)


def test_a_well_constrained_registration_measures_the_base_moved_as_the_camera_was() -> None:
    base = np.array([1.0, -2.0, 0.3])
    frame = _frame(base)
    shift = np.array([0.04, -0.03, math.radians(1.0)])
    m = measure(_result(frame, shift, np.eye(6) * 1e6), frame, base, POINTS, P)
    assert isinstance(m, Measurement)
    np.testing.assert_allclose(m.pose, se2.compose(shift, base), atol=1e-9)
    assert m.directions.dof == 3


@pytest.mark.parametrize(("converged", "inliers", "expected"),
                         [(False, 400, Verdict.NOT_CONVERGED), (True, 10, Verdict.FEW_INLIERS)])
def test_a_registration_that_fails_its_gates_measures_nothing(converged, inliers, expected) -> None:
    base = np.zeros(3)
    frame = _frame(base)
    result = _result(frame, np.zeros(3), np.eye(6) * 1e6, converged=converged, inliers=inliers)
    assert measure(result, frame, base, POINTS, P) == expected


def test_a_registration_whose_points_constrain_no_direction_is_degenerate() -> None:
    base = np.zeros(3)
    frame = _frame(base)
    assert measure(_result(frame, np.zeros(3), np.zeros((6, 6))), frame, base, POINTS, P) == Verdict.DEGENERATE
