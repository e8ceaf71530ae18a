"""A snapshot as Foxglove's well-known messages (protobuf, from `foxglove-sdk`), the ones its 3D panel draws.

One encoder for both sinks: the recorder writes these bytes into its MCAP chunks with the schemas the SDK
carries (`SCHEMAS`), and the live server (`app.foxglove_live`) logs the same bytes on SDK channels.

| topic | schema | what |
| --- | --- | --- |
| `/tf` | `foxglove.FrameTransforms` | world → base (q[0:3]) → arm links, cameras; world → base_estimated, base_true |
| `/robot/model` | `foxglove.SceneUpdate` | the robot: UR10 link meshes embedded (GLB), the base's boxes; re-sent |
| `/scene/boxes` | `foxglove.SceneUpdate` | ground-truth boxes (metadata: id, yaw, dark) |
| `/map/objects` | `foxglove.SceneUpdate` | mapped objects coloured by E[v] (green → red, removed grey), '#id name' |
| `/plan/paths` | `foxglove.SceneUpdate` | predicted base and EE paths, the planned base path, the targets |
| `/map/points`, `/camera/clouds` | `foxglove.PointCloud` | map points, decimated depth points (world, float32 x y z) |
| `/camera/<name>/depth` | `foxglove.RawImage` | depth in metres (32FC1, 0 = no return), frame `camera_<name>` |

Every SceneUpdate first deletes all entities of its topic, so each message is the whole picture: a seek or a
late subscriber never sees stale boxes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from functools import cache

import foxglove
import numpy as np
import trimesh
import trimesh.visual
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    FrameTransform,
    FrameTransforms,
    KeyValuePair,
    LinePrimitive,
    ModelPrimitive,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    PointCloud,
    Pose,
    Quaternion,
    RawImage,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)
from scipy.spatial.transform import Rotation

from app.object_label import object_label, operator_names
from app.runtime.snapshot import Snapshot
from app.runtime.target_marks import TargetMark
from app.ui.colors import consistency_rgb
from core.params import MappingParams
from core.robot.model import RobotModel
from core.robot.ur10_assets import ARM_LINKS, ur10_mesh
from core.scene import Box
from core.types import DepthFrame, ObjectMapSnapshot, ObjectStatus, Plan

WORLD = "world"
BASE = "base"
CAMERA_FRAMES = ("camera_hand", "camera_base")
BASE_POSE_FRAMES: dict[str, str] = {"base_estimated": "base_estimate", "base_true": "base_true"}
"""Frame → Snapshot attribute holding a base pose [x, y, yaw]: a snapshot whose attribute is not None gets world →
frame in `/tf` beside world → base (the pose the controller drives): `base_estimated` the localizer's estimate (with
localization on; the same pose as `base`), `base_true` the simulator's truth (simulation only)."""

PROTOBUF_TOPICS: dict[str, str] = {
    "/tf": "foxglove.FrameTransforms", "/robot/model": "foxglove.SceneUpdate", "/scene/boxes": "foxglove.SceneUpdate",
    "/map/objects": "foxglove.SceneUpdate", "/plan/paths": "foxglove.SceneUpdate",
    "/map/points": "foxglove.PointCloud", "/camera/clouds": "foxglove.PointCloud",
}
SCHEMAS: dict[str, foxglove.Schema] = {s.name: s for s in (
    FrameTransforms.get_schema(), SceneUpdate.get_schema(), PointCloud.get_schema(), RawImage.get_schema())}
"""Protobuf schemas (FileDescriptorSet) by name, as the SDK defines them."""


def depth_topic(camera: str) -> str:
    return f"/camera/{camera}/depth"


# --- small conversions ----------------------------------------------------------------------------------


def timestamp(t_s: float) -> Timestamp:
    sec = math.floor(t_s)
    return Timestamp(sec, min(int(round((t_s - sec) * 1e9)), 999_999_999))


def _vec(p: Iterable[float]) -> Vector3:
    x, y, z = (float(c) for c in p)
    return Vector3(x=x, y=y, z=z)


def _quat(q: Iterable[float] | None) -> Quaternion:
    x, y, z, w = (0.0, 0.0, 0.0, 1.0) if q is None else (float(c) for c in q)
    return Quaternion(x=x, y=y, z=z, w=w)


def _pose(position: Iterable[float], quaternion: Iterable[float] | None = None) -> Pose:
    return Pose(position=_vec(position), orientation=_quat(quaternion))


def _color(rgb: Iterable[float], a: float = 1.0) -> Color:
    r, g, b = (float(c) / 255.0 for c in rgb)
    return Color(r=r, g=g, b=b, a=a)


def _yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def _planar(x: float, y: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = (x, y)
    return T


_DELETE_ALL = [SceneEntityDeletion(type=SceneEntityDeletionType.All)]


def _scene(entities: list[SceneEntity]) -> bytes:
    """The whole picture of a topic: delete what was drawn, draw these."""
    return SceneUpdate(deletions=_DELETE_ALL, entities=entities).encode()


# --- transforms -------------------------------------------------------------------------------------------


def transforms(robot: RobotModel, snap: Snapshot, t_s: float | None = None) -> bytes:
    """world → base from q[0:3], base → every arm link and camera from FK, world → each extra base pose."""
    q = np.asarray(snap.state.q, float)
    stamp = timestamp(snap.state.t if t_s is None else t_s)
    names = (*ARM_LINKS, *CAMERA_FRAMES)
    poses = robot.frame_poses(q, names)
    T_base_world = np.linalg.inv(_planar(q[0], q[1], q[2]))
    out = [FrameTransform(timestamp=stamp, parent_frame_id=WORLD, child_frame_id=BASE,
                          translation=_vec((q[0], q[1], 0.0)), rotation=_quat(_yaw_quat(q[2])))]
    T = T_base_world @ np.stack([poses[name] for name in names])
    quaternions = Rotation.from_matrix(T[:, :3, :3]).as_quat()
    out += [FrameTransform(timestamp=stamp, parent_frame_id=BASE, child_frame_id=name, translation=_vec(T[i, :3, 3]),
                           rotation=_quat(quaternions[i])) for i, name in enumerate(names)]
    for frame, attribute in BASE_POSE_FRAMES.items():
        pose = getattr(snap, attribute, None)
        if pose is not None:
            x, y, yaw = (float(c) for c in np.asarray(pose, float)[:3])
            out.append(FrameTransform(timestamp=stamp, parent_frame_id=WORLD, child_frame_id=frame,
                                      translation=_vec((x, y, 0.0)), rotation=_quat(_yaw_quat(yaw))))
    return FrameTransforms(transforms=out).encode()


# --- the robot model --------------------------------------------------------------------------------------

_LINK_RGB = (150, 160, 175)
_BASE_RGB = ((45, 45, 50), (60, 60, 66))


Z_UP_TO_GLTF = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
"""(x, y, z) → (x, z, −y): glTF is y-up, and Foxglove turns every glTF model +90° about x into its z-up frames."""


@cache
def link_glb(link: str) -> bytes:
    """A UR10 link's collision mesh (what the studio draws) as binary glTF (y-up, as glTF wants: Foxglove
    draws it in the link's frame), for ModelPrimitive's `data`."""
    loaded = trimesh.load(ur10_mesh(link, "collision"))
    mesh = loaded.to_geometry() if isinstance(loaded, trimesh.Scene) else loaded
    if not isinstance(mesh, trimesh.Trimesh):
        raise TypeError(f"{ur10_mesh(link, 'collision')} holds no triangle mesh")
    mesh = mesh.copy()
    mesh.apply_transform(Z_UP_TO_GLTF)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=(*_LINK_RGB, 255))
    data = mesh.export(file_type="glb")
    if not isinstance(data, bytes):
        raise TypeError(f"trimesh exported {type(data).__name__} for a GLB, expected bytes")
    return data


def robot_model(robot: RobotModel, t_s: float) -> bytes:
    """The robot drawn in its own frames: each arm link's mesh (embedded GLB) and the base's boxes."""
    stamp = timestamp(t_s)
    entities = [SceneEntity(timestamp=stamp, frame_id=BASE, id="robot/base", frame_locked=True, cubes=[
        CubePrimitive(pose=_pose(box.centre_m), size=_vec(2 * h for h in box.half_m), color=_color(rgb))
        for box, rgb in zip(robot.boxes, _BASE_RGB, strict=True)])]
    entities += [SceneEntity(timestamp=stamp, frame_id=link, id=f"robot/{link}", frame_locked=True, models=[
        ModelPrimitive(pose=_pose((0.0, 0.0, 0.0)), scale=_vec((1.0, 1.0, 1.0)), color=_color(_LINK_RGB),
                       media_type="model/gltf-binary", data=link_glb(link))]) for link in ARM_LINKS]
    return _scene(entities)


# --- the world and the map --------------------------------------------------------------------------------


def boxes(t_s: float, scene_boxes: Iterable[Box]) -> bytes:
    """Ground-truth boxes; metadata keeps what a cube does not say (id, yaw, dark) for readers."""
    stamp = timestamp(t_s)
    return _scene([SceneEntity(
        timestamp=stamp, frame_id=WORLD, id=f"box/{b.id}",
        metadata=[KeyValuePair(key="id", value=b.id), KeyValuePair(key="yaw", value=repr(float(b.yaw))),
                  KeyValuePair(key="dark", value=str(bool(getattr(b, "dark", False))).lower())],
        cubes=[CubePrimitive(pose=_pose(b.position, _yaw_quat(b.yaw)), size=_vec(b.size),
                             color=_color((20, 20, 20) if getattr(b, "dark", False) else (190, 150, 100), 0.6))])
        for b in scene_boxes])


_REMOVED_RGB = (140, 140, 140)


def mapped_objects(t_s: float, object_map: ObjectMapSnapshot, theta_stat: float,
                   names: Mapping[int, str] | None = None) -> bytes:
    """Each mapped object as a box coloured by its consistency E[v] with its label '#4 E[v]=0.93' ('#4 shelf …'
    with the operator's `names` by map id), as the studio labels it."""
    stamp, names = timestamp(t_s), names or {}
    entities = []
    poses = np.array([np.asarray(o.pose, float) for o in object_map.objects]).reshape(-1, 4, 4)
    quaternions = Rotation.from_matrix(poses[:, :3, :3]).as_quat() if len(poses) else poses
    for o, pose, quaternion in zip(object_map.objects, poses, quaternions, strict=True):
        e_v = float(o.consistency)
        removed = o.status != ObjectStatus.ACTIVE
        rgb = _REMOVED_RGB if removed or not math.isfinite(e_v) else consistency_rgb(e_v, theta_stat)
        top = pose[:3, 3] + (0.0, 0.0, float(np.asarray(o.extent, float)[2]) / 2 + 0.15)
        entities.append(SceneEntity(
            timestamp=stamp, frame_id=WORLD, id=f"object/{o.id}",
            metadata=[KeyValuePair(key="E[v]", value=f"{e_v:.3f}"), KeyValuePair(key="status", value=o.status.value),
                      KeyValuePair(key="name", value=names.get(o.id, ""))],
            cubes=[CubePrimitive(pose=_pose(pose[:3, 3], quaternion), size=_vec(o.extent), color=_color(rgb, 0.5))],
            texts=[TextPrimitive(pose=_pose(top), billboard=True, font_size=14.0, scale_invariant=True,
                                 color=_color(rgb), text=f"{object_label(o.id, names.get(o.id))} E[v]={e_v:.2f}")]))
    return _scene(entities)


# --- plans and targets ------------------------------------------------------------------------------------


def _line(points: np.ndarray, rgb: tuple[int, int, int], thickness: float) -> LinePrimitive:
    return LinePrimitive(thickness=thickness, scale_invariant=False, color=_color(rgb),
                         points=[Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in points])


def _lifted(path: np.ndarray | None, z: float) -> np.ndarray | None:
    if path is None or len(path) < 2:
        return None
    path = np.asarray(path, float)
    return np.column_stack([path[:, :2], np.full(len(path), z)])


def _target(mark: TargetMark, active: bool) -> SceneEntity:
    rgb = (230, 40, 200) if active else (150, 90, 160)
    size = 0.12 if mark.goal else 0.07
    frame = BASE if mark.frame == "base" else WORLD
    spheres = [SpherePrimitive(pose=_pose(mark.position), size=_vec((size,) * 3), color=_color(rgb))]
    arrows = [] if mark.quaternion is None else [ArrowPrimitive(
        pose=_pose(mark.position, mark.quaternion), shaft_length=0.2, shaft_diameter=0.03, head_length=0.08,
        head_diameter=0.07, color=_color(rgb))]
    label = TextPrimitive(pose=_pose(np.add(mark.position, (0.0, 0.0, 0.12))), billboard=True, font_size=12.0,
                          scale_invariant=True, color=_color(rgb), text=mark.name)
    return SceneEntity(frame_id=frame, id=f"target/{mark.index}/{mark.position}", texts=[label] if mark.goal else [],
                       spheres=spheres, arrows=arrows)


def plan_paths(t_s: float, plan: Plan | None, base_path: np.ndarray | None, targets: Iterable[TargetMark],
               active_index: int) -> bytes:
    """Blue predicted base path, orange predicted EE path, grey planned base path; targets (active in magenta)."""
    stamp = timestamp(t_s)
    lines = []
    if plan is not None:
        predicted = _lifted(plan.base_path, 0.02)
        if predicted is not None:
            lines.append(("plan/predicted_base", _line(predicted, (40, 110, 240), 0.03)))
        if plan.ee_path is not None and len(plan.ee_path) >= 2:
            lines.append(("plan/predicted_ee", _line(np.asarray(plan.ee_path, float)[:, :3], (245, 140, 20), 0.02)))
    planned = _lifted(base_path, 0.01)
    if planned is not None:
        lines.append(("plan/planned_base", _line(planned, (120, 120, 120), 0.015)))
    entities = [SceneEntity(timestamp=stamp, frame_id=WORLD, id=name, lines=[line]) for name, line in lines]
    entities += [_target(m, m.index == active_index) for m in targets]
    return _scene(entities)


# --- clouds and images ------------------------------------------------------------------------------------

_XYZ = [PackedElementField(name=n, offset=4 * i, type=PackedElementFieldNumericType.Float32)
        for i, n in enumerate("xyz")]


def point_cloud(t_s: float, points: np.ndarray) -> bytes:
    """World points as float32 x, y, z."""
    data = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 3), dtype="<f4")
    return PointCloud(timestamp=timestamp(t_s), frame_id=WORLD, pose=_pose((0.0, 0.0, 0.0)), point_stride=12,
                      fields=_XYZ, data=data.tobytes()).encode()


def depth_image(frame: DepthFrame, t_s: float | None = None) -> bytes:
    """A depth frame as a raw image: float32 metres, 0 = no return, in the camera's frame."""
    depth = np.ascontiguousarray(frame.depth, dtype="<f4")
    return RawImage(timestamp=timestamp(frame.t if t_s is None else t_s), frame_id=f"camera_{frame.camera}",
                    width=depth.shape[1], height=depth.shape[0], encoding="32FC1", step=4 * depth.shape[1],
                    data=depth.tobytes()).encode()


# --- one snapshot -----------------------------------------------------------------------------------------


def scene_messages(robot: RobotModel, snap: Snapshot, with_points: bool, with_model: bool, t_s: float | None = None,
                   theta_stat: float = MappingParams().theta_stat) -> list[tuple[str, bytes]]:
    """The (topic, protobuf bytes) of one snapshot's Foxglove channels (`PROTOBUF_TOPICS`), stamped `t_s`: the
    clock of the log times (wall clock live, whose simulation time pauses and resets), else simulation time."""
    t = snap.state.t if t_s is None else t_s
    out = [("/tf", transforms(robot, snap, t))]
    if with_model:
        out.append(("/robot/model", robot_model(robot, t)))
    out.append(("/scene/boxes", boxes(t, snap.boxes)))
    if snap.object_map is not None:
        out.append(("/map/objects", mapped_objects(t, snap.object_map, theta_stat, operator_names(snap.anchors))))
    out.append(("/plan/paths", plan_paths(t, snap.plan, snap.base_path, getattr(snap, "targets", ()),
                                          snap.active_index)))
    if with_points and snap.map_points is not None:
        out.append(("/map/points", point_cloud(t, snap.map_points)))
    if with_points and snap.clouds is not None:
        out.append(("/camera/clouds", point_cloud(t, snap.clouds)))
    return out
