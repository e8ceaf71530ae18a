"""The kinematic model: UR10 URDF on a planar (x, y, yaw) base, built in pinocchio.

q = [x, y, yaw, shoulder_pan, shoulder_lift, elbow, wrist_1, wrist_2, wrist_3]. Extra frames: `mobile_base`
(after the yaw joint), `ee` (the UR10 `ee_link`, x along the tool), cameras (OpenCV axes: z forward,
x right, y down) and one frame per collision sphere, so numeric and symbolic FK read one table.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin

from core.errors import StudioError
from core.params import RobotParams
from core.robot.collision_boxes import CollisionBox, base_boxes
from core.robot.collision_spheres import SPHERES, CollisionSphere
from core.robot.limits import JointLimits
from core.robot.ur10_assets import ARM_LINKS, ur10_urdf

BASE_JOINTS = ("base_x", "base_y", "base_yaw")
ARM_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")

# Camera frames: rotation from the parent frame to OpenCV camera axes (z forward along parent x).
_R_X_FORWARD_TO_CV = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


class RobotModelError(StudioError, RuntimeError):
    """The URDF does not describe the 9-joint robot (base x, y, yaw and the UR10's six joints)."""


@dataclass(frozen=True)
class CameraMount:
    """A camera frame: `offset_m` in `link`, looking along the link's x axis pitched down by `pitch_deg`."""

    name: str
    link: str
    offset_m: tuple[float, float, float]
    pitch_deg: float = 0.0

    def placement(self) -> pin.SE3:
        p = np.deg2rad(self.pitch_deg)
        pitch = np.array([[np.cos(p), 0.0, np.sin(p)], [0.0, 1.0, 0.0], [-np.sin(p), 0.0, np.cos(p)]])
        return pin.SE3(pitch @ _R_X_FORWARD_TO_CV, np.array(self.offset_m))


CAMERAS: tuple[CameraMount, ...] = (
    CameraMount("hand", "ee", (0.0, 0.0, 0.08)),
    CameraMount("base", "mobile_base", (0.50, 0.0, 0.38), pitch_deg=12.0),
)
"""The paper's two depth cameras: one on the wrist (hand), one on the base looking forward."""

READY_Q = np.array([0.0, 0.0, 0.0, 0.0, -1.6, 2.2, -0.2, np.pi / 2, np.pi])
"""A ready pose: arm folded in front of the base (EE at 0.76 m ahead, 0.93 m up), hand camera upright
looking ahead and 23° down."""


def _body_inertia(mass: float, size: tuple[float, float, float], z: float) -> pin.Inertia:
    lx, ly, lz = size
    inertia = np.diag([ly**2 + lz**2, lx**2 + lz**2, lx**2 + ly**2]) * mass / 12.0
    return pin.Inertia(mass, np.array([0.0, 0.0, z]), inertia)


def _build(params: RobotParams) -> pin.Model:
    base = pin.Model()
    base.name = "ur10_on_omnibase"
    identity = pin.SE3.Identity()
    jx = base.addJoint(0, pin.JointModelPX(), identity, "base_x")
    jy = base.addJoint(jx, pin.JointModelPY(), identity, "base_y")
    jyaw = base.addJoint(jy, pin.JointModelRZ(), identity, "base_yaw")
    base.appendBodyToJoint(jyaw, _body_inertia(135.0, params.base_size_m, params.base_size_m[2] / 2), identity)
    base_frame = base.addFrame(pin.Frame("mobile_base", jyaw, identity, pin.FrameType.BODY))
    mount = pin.SE3(np.eye(3), np.array(params.arm_mount_xyz_m))
    model = pin.appendModel(base, pin.buildModelFromUrdf(str(ur10_urdf())), base_frame, mount)
    ee = model.getFrameId("ee_link")
    model.addFrame(pin.Frame("ee", model.frames[ee].parentJoint, model.frames[ee].placement, pin.FrameType.OP_FRAME))
    for cam in CAMERAS:
        parent = model.frames[model.getFrameId(cam.link)]
        model.addFrame(pin.Frame(f"camera_{cam.name}", parent.parentJoint, parent.placement * cam.placement(),
                                 pin.FrameType.OP_FRAME))
    for sphere in SPHERES:
        parent = model.frames[model.getFrameId(sphere.link)]
        offset = pin.SE3(np.eye(3), np.array(sphere.offset_m))
        model.addFrame(pin.Frame(f"sphere_{sphere.name}", parent.parentJoint, parent.placement * offset,
                                 pin.FrameType.OP_FRAME))
    return model


def _limits(model: pin.Model, params: RobotParams) -> JointLimits:
    q_min = np.array(model.lowerPositionLimit, dtype=float)
    q_max = np.array(model.upperPositionLimit, dtype=float)
    q_min[:3], q_max[:3] = -np.inf, np.inf
    return JointLimits(q_min=q_min, q_max=q_max, v_max=params.v_max, a_max=params.a_max)


class RobotModel:
    """The robot's kinematics and limits; numeric FK by pinocchio (thread-safe: fresh data per call)."""

    nq = 9
    link_names: tuple[str, ...] = ("mobile_base", *ARM_LINKS)

    def __init__(self, params: RobotParams | None = None) -> None:
        self.params = params or RobotParams()
        self.model = _build(self.params)
        if self.model.nq != self.nq:
            raise RobotModelError(f"expected 9 joints, the URDF gave {self.model.nq}")
        self.limits = _limits(self.model, self.params)
        self.spheres: tuple[CollisionSphere, ...] = SPHERES
        self.boxes: tuple[CollisionBox, ...] = base_boxes(self.params)
        self.cameras: tuple[CameraMount, ...] = CAMERAS

    @cached_property
    def sphere_radii(self) -> np.ndarray:
        """Radii r_j (m) of the collision spheres, in table order."""
        return np.array([s.radius_m for s in self.spheres])

    @cached_property
    def _sphere_frame_ids(self) -> list[int]:
        return [self.model.getFrameId(f"sphere_{s.name}") for s in self.spheres]

    def has_frame(self, name: str) -> bool:
        """Whether the model has a frame of that name."""
        return bool(self.model.existFrame(name))

    def frame_id(self, name: str) -> int:
        """Index of a frame; KeyError with the known names if absent."""
        if not self.model.existFrame(name):
            raise KeyError(f"no frame {name!r}; frames: {[f.name for f in self.model.frames]}")
        return self.model.getFrameId(name)

    def _placements(self, q: np.ndarray) -> pin.Data:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.nq,) or not np.all(np.isfinite(q)):
            raise ValueError(f"q must be 9 finite numbers, got {q!r}")
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q)
        return data

    def frame_pose(self, q: np.ndarray, name: str) -> np.ndarray:
        """World pose (4×4) of a frame at q."""
        fid = self.frame_id(name)
        return self._placements(q).oMf[fid].homogeneous.copy()

    def frame_poses(self, q: np.ndarray, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """World poses (4×4) of several frames from one FK pass."""
        ids = [self.frame_id(n) for n in names]
        data = self._placements(q)
        return {n: data.oMf[i].homogeneous.copy() for n, i in zip(names, ids, strict=True)}

    def ee_pose(self, q: np.ndarray) -> np.ndarray:
        """World pose (4×4) of the end effector (`ee`: UR10 `ee_link`, x along the tool)."""
        return self.frame_pose(q, "ee")

    def camera_pose(self, q: np.ndarray, camera: str) -> np.ndarray:
        """T_world_camera (4×4, OpenCV axes) of camera `hand` or `base`."""
        return self.frame_pose(q, f"camera_{camera}")

    def sphere_centres(self, q: np.ndarray) -> np.ndarray:
        """Centres P_j(q) (M×3) of the collision spheres in the world."""
        data = self._placements(q)
        return np.array([data.oMf[i].translation for i in self._sphere_frame_ids])

    def link_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """World poses of the base and of every UR10 link with a mesh, for drawing."""
        return self.frame_poses(q, self.link_names)

    def frame_jacobian(self, q: np.ndarray, name: str) -> np.ndarray:
        """6×9 Jacobian [linear; angular] of a frame, in world-aligned axes at the frame's origin."""
        data = self._placements(q)
        return pin.computeFrameJacobian(self.model, data, np.asarray(q, float), self.frame_id(name),
                                        pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)

    def random_q(self, rng: np.random.Generator, base_span_m: float = 3.0) -> np.ndarray:
        """A random configuration within limits (base within ±base_span_m, yaw within ±π)."""
        lo = np.maximum(self.limits.q_min, -np.pi)
        hi = np.minimum(self.limits.q_max, np.pi)
        lo[:2], hi[:2] = -base_span_m, base_span_m
        return rng.uniform(lo, hi)
