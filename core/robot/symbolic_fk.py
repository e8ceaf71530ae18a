"""Symbolic forward kinematics in casadi, built from pinocchio's joint placements and axes.

`pinocchio.casadi` is not in the pin wheel, so we rebuild the chain oMi = oM_parent · jointPlacement ·
M_joint(q_i) with casadi SX. The controller differentiates these expressions; the tests check them
against pinocchio to 1e-9.
"""

from __future__ import annotations

from functools import cached_property

import casadi as ca
import numpy as np

from core.robot.model import RobotModel
from core.types import vec3

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}

Transform = tuple[ca.SX, ca.SX]
"""(R 3×3, p 3×1) of a rigid transform."""


def _rotation(axis: tuple[float, float, float], angle: ca.SX) -> ca.SX:
    """Rodrigues' formula for a unit axis."""
    k = ca.SX(np.array(axis, dtype=float).reshape(3, 1))
    K = ca.skew(k)
    return ca.SX.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


def _joint_motion(shortname: str, joint, qi: ca.SX) -> Transform:
    """Transform across one joint for its coordinate qi."""
    if shortname in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = vec3(np.asarray(joint.axis).ravel())
        revolute = shortname.startswith("JointModelRevolute")
    elif shortname[-2] in "RP" and shortname[-1] in _AXES and shortname.startswith("JointModel"):
        axis, revolute = _AXES[shortname[-1]], shortname[-2] == "R"
    else:
        raise NotImplementedError(f"joint type {shortname} has no symbolic form")
    if revolute:
        return _rotation(axis, qi), ca.SX.zeros(3, 1)
    return ca.SX.eye(3), ca.SX(np.array(axis).reshape(3, 1)) * qi


def _const(se3) -> Transform:
    return ca.SX(se3.rotation), ca.SX(se3.translation.reshape(3, 1))


def _compose(a: Transform, b: Transform) -> Transform:
    return a[0] @ b[0], a[0] @ b[1] + a[1]


class SymbolicKinematics:
    """casadi expressions and functions for frame poses and collision-sphere centres."""

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot
        self.q = ca.SX.sym("q", robot.nq)
        self._joints = self._chain(self.q)

    def _chain(self, q: ca.SX) -> list[Transform]:
        model = self.robot.model
        oMi: list[Transform] = [(ca.SX.eye(3), ca.SX.zeros(3, 1))]
        for j in range(1, model.njoints):
            joint = model.joints[j]
            motion = _joint_motion(joint.shortname(), joint, q[joint.idx_q])
            placed = _compose(oMi[model.parents[j]], _const(model.jointPlacements[j]))
            oMi.append(_compose(placed, motion))
        return oMi

    def frame(self, name: str) -> Transform:
        """(R, p) of a frame as expressions of `self.q`."""
        frame = self.robot.model.frames[self.robot.frame_id(name)]
        return _compose(self._joints[frame.parentJoint], _const(frame.placement))

    def sphere_centres(self) -> ca.SX:
        """3×M matrix of collision-sphere centres P_j(q)."""
        return ca.horzcat(*[self.frame(f"sphere_{s.name}")[1] for s in self.robot.spheres])

    @cached_property
    def ee_function(self) -> ca.Function:
        """q ↦ (p_ee 3×1, R_ee 3×3)."""
        R, p = self.frame("ee")
        return ca.Function("ee_pose", [self.q], [p, R], ["q"], ["p", "R"])

    @cached_property
    def spheres_function(self) -> ca.Function:
        """q ↦ sphere centres 3×M."""
        return ca.Function("sphere_centres", [self.q], [self.sphere_centres()], ["q"], ["P"])

    @cached_property
    def ee_jacobian_function(self) -> ca.Function:
        """q ↦ (dp/dq 3×9, d vec(R)/dq 9×9 with vec column-major)."""
        R, p = self.frame("ee")
        return ca.Function("ee_jac", [self.q], [ca.jacobian(p, self.q), ca.jacobian(ca.vec(R), self.q)])

    @cached_property
    def spheres_jacobian_function(self) -> ca.Function:
        """q ↦ d vec(P)/dq (3M×9): rows 3j..3j+2 are the Jacobian of sphere j's centre."""
        P = self.sphere_centres()
        return ca.Function("spheres_jac", [self.q], [ca.jacobian(ca.vec(P), self.q)])
