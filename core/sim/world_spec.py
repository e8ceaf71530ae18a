"""Generate the MuJoCo model in code from `core.robot` (URDF `package://` paths do not load in MuJoCo).

Bodies mirror pinocchio's joints one to one (same placements and axes), so MuJoCo's kinematics equal
the controller's. The base carries slide x, slide y and hinge yaw; every joint has a velocity
actuator. Boxes live in a pool of mocap bodies ("slots"): moving one is a pose write, adding or
removing one fills or parks a slot, and only growing the pool recompiles (see `SimWorld`).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from core.params import SimParams
from core.robot.model import RobotModel
from core.robot.ur10_assets import ARM_LINKS, ur10_mesh
from core.scene import Box

ROBOT_CONTYPE, BOX_CONAFFINITY = 1, 1
"""Robot geoms collide with boxes only (no self-collision, no floor contact); boxes never with boxes."""
PARKED_Z_M = -5.0
"""Height of a free box slot: under the floor, out of every camera's view and of all contacts."""
_ROBOT_RGBA = (0.55, 0.6, 0.68, 1.0)
_BASE_RGBA = (0.2, 0.2, 0.22, 1.0)
_BOX_RGBA = (0.76, 0.6, 0.42, 1.0)
DARK_BOX_RGBA = (0.08, 0.08, 0.09, 1.0)
"""Boxes whose surface returns no depth are drawn black."""
_MJ_FROM_CV = np.diag([1.0, -1.0, -1.0])
"""MuJoCo cameras look along −z with y up; OpenCV cameras along +z with y down."""


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q


def _add_robot(spec: mujoco.MjSpec, robot: RobotModel) -> None:
    model = robot.model
    bodies: dict[int, mujoco.MjsBody] = {}
    base = spec.worldbody.add_body(name="mobile_base", gravcomp=1.0)
    for axis, name in (((1, 0, 0), "base_x"), ((0, 1, 0), "base_y")):
        base.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis, armature=1.0)
    base.add_joint(name="base_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=(0, 0, 1), armature=1.0)
    bodies[model.getJointId("base_yaw")] = base
    for box, mass in zip(robot.boxes, (135.0, 10.0), strict=True):  # the body, then the rack
        base.add_geom(name=box.name, type=mujoco.mjtGeom.mjGEOM_BOX, size=box.half_m, pos=box.centre_m,
                      rgba=_BASE_RGBA, mass=mass, contype=ROBOT_CONTYPE, conaffinity=0)
    for j in range(model.getJointId("base_yaw") + 1, model.njoints):
        placement = model.jointPlacements[j]
        body = bodies[model.parents[j]].add_body(name=model.names[j].removesuffix("_joint") + "_body",
                                                 pos=placement.translation, quat=_quat(placement.rotation),
                                                 gravcomp=1.0)
        axis = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1)}[model.joints[j].shortname()[-1]]
        iq = model.joints[j].idx_q
        lo, hi = model.lowerPositionLimit[iq], model.upperPositionLimit[iq]
        body.add_joint(name=model.names[j], type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis, range=(lo, hi),
                       limited=mujoco.mjtLimited.mjLIMITED_TRUE, armature=0.1)
        inertia = model.inertias[j]
        body.mass, body.ipos = max(inertia.mass, 0.1), inertia.lever
        body.inertia = np.maximum(np.diag(inertia.inertia), 1e-3)
        body.explicitinertial = True
        bodies[j] = body
    for link in ARM_LINKS:
        frame = model.frames[model.getFrameId(link)]
        spec.add_mesh(name=f"mesh_{link}", file=str(ur10_mesh(link, "collision")))
        bodies[frame.parentJoint].add_geom(
            name=f"geom_{link}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"mesh_{link}",
            pos=frame.placement.translation, quat=_quat(frame.placement.rotation), rgba=_ROBOT_RGBA,
            contype=ROBOT_CONTYPE, conaffinity=0, mass=0.0 if link != "base_link" else 4.0)
    _add_frames(robot, bodies)


def _add_frames(robot: RobotModel, bodies: dict[int, mujoco.MjsBody]) -> None:
    """Cameras and sites at the frames of `RobotModel` (EE, sphere centres), for checks and rendering."""
    model = robot.model
    for cam in robot.cameras:
        frame = model.frames[robot.frame_id(f"camera_{cam.name}")]
        R = frame.placement.rotation @ _MJ_FROM_CV
        bodies[frame.parentJoint].add_camera(name=f"camera_{cam.name}", pos=frame.placement.translation,
                                             quat=_quat(R), fovy=58.0)
    for name in ("ee", *[f"sphere_{s.name}" for s in robot.spheres]):
        frame = model.frames[robot.frame_id(name)]
        bodies[frame.parentJoint].add_site(name=name, pos=frame.placement.translation,
                                           quat=_quat(frame.placement.rotation), group=5, size=(0.01, 0.01, 0.01))


def _add_velocity_actuators(spec: mujoco.MjSpec, robot: RobotModel) -> None:
    names = ["base_x", "base_y", "base_yaw", *[robot.model.names[j] for j in range(4, 10)]]
    for name, vmax in zip(names, robot.limits.v_max, strict=True):
        act = spec.add_actuator(name=f"vel_{name}", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=100.0)  # retuned per joint after compilation (SimWorld._tune_gains)
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = (-vmax, vmax)


def _add_room(spec: mujoco.MjSpec, params: SimParams) -> None:
    half = params.room_half_size_m + (0.0 if params.walls else params.floor_beyond_room_m)
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=(half, half, 0.1),
                            rgba=(0.82, 0.83, 0.85, 1), contype=0, conaffinity=0)
    spec.worldbody.add_light(name="sun", pos=(0, 0, 6), dir=(0, 0, -1), type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    for i, wall in enumerate(wall_boxes(params)):
        spec.worldbody.add_geom(name=f"wall_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=np.array(wall.size) / 2,
                                pos=wall.position, rgba=(0.9, 0.9, 0.88, 1), contype=0, conaffinity=BOX_CONAFFINITY)


def wall_boxes(params: SimParams) -> tuple[Box, ...]:
    """The optional room walls as boxes (1.2 m high, 0.1 m thick), for geometry and ground truth alike."""
    if not params.walls:
        return ()
    half, t, h = params.room_half_size_m, 0.1, 1.2
    return (Box("wall_east", (half, 0.0, h / 2), (t, 2 * half, h)),
            Box("wall_west", (-half, 0.0, h / 2), (t, 2 * half, h)),
            Box("wall_north", (0.0, half, h / 2), (2 * half, t, h)),
            Box("wall_south", (0.0, -half, h / 2), (2 * half, t, h)))


def add_box_slots(spec: mujoco.MjSpec, first: int, count: int) -> None:
    """Append `count` parked mocap box bodies named `box_slot_<k>`."""
    for k in range(first, first + count):
        body = spec.worldbody.add_body(name=f"box_slot_{k}", mocap=True, pos=(0, 0, PARKED_Z_M))
        body.add_geom(name=f"box_geom_{k}", type=mujoco.mjtGeom.mjGEOM_BOX, size=(0.05, 0.05, 0.05),
                      rgba=_BOX_RGBA, contype=0, conaffinity=BOX_CONAFFINITY)


def build_world_spec(robot: RobotModel, params: SimParams, box_slots: int) -> mujoco.MjSpec:
    """The whole world: room, robot with actuators and cameras, `box_slots` parked boxes."""
    spec = mujoco.MjSpec()
    spec.modelname = "perceptive_htmpc_world"
    spec.compiler.degree = False
    spec.option.timestep = params.timestep_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.stat.extent = 10.0  # fixes the clip planes: parked slots must not change the depth range
    spec.stat.center = (0, 0, 0.5)
    spec.visual.map.znear = 0.005
    spec.visual.map.zfar = 5.0
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    _add_room(spec, params)
    _add_robot(spec, robot)
    _add_velocity_actuators(spec, robot)
    add_box_slots(spec, 0, box_slots)
    return spec


def box_rgba(box: Box) -> tuple[float, float, float, float]:
    """Colour of a box's geom: black if its surface returns no depth."""
    return DARK_BOX_RGBA if box.dark else _BOX_RGBA


def se3_to_pos_quat(T: pin.SE3 | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position, wxyz quaternion) of a 4×4 transform."""
    M = np.asarray(T) if isinstance(T, np.ndarray) else T.homogeneous
    return M[:3, 3].copy(), _quat(M[:3, :3])
