"""Draw what the robot believes: mapped objects coloured by E[v] with labels, removed objects,
the map's occupied points, an EDF slice, collision spheres, camera frusta and depth point clouds."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import trimesh
import viser

from app.object_label import object_label, operator_names
from app.runtime.snapshot import Snapshot
from app.ui.colors import consistency_rgb, distance_rgb
from app.ui.label_layout import FixedLabel, View, screen_stacked, stacked
from app.ui.robot_view import wxyz
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import MappedObject, ObjectStatus

LABEL_LIFT_M = 0.15
"""A label floats this far above its object's top."""


def age_text(seconds: float) -> str:
    """How long ago an object was last seen, coarse enough that the label changes rarely: 'seen now',
    'seen 4 s ago', 'seen 2 min ago'."""
    if not np.isfinite(seconds):
        return "never seen"
    if seconds < 1.0:
        return "seen now"
    return f"seen {seconds:.0f} s ago" if seconds < 60 else f"seen {seconds // 60:.0f} min ago"


def label_text(obj: MappedObject, removed: bool, now_s: float, name: str | None = None) -> str:
    """'#4 E[v]=0.93 · seen 4 s ago', '#5 removed · seen 12 s ago'."""
    state = "removed" if removed else f"E[v]={obj.consistency:.2f}"
    return f"{object_label(obj.id, name)} {state} · {age_text(now_s - obj.last_seen_t)}"


@dataclass(frozen=True)
class DrawnObject:
    """A mapped object as the view draws it: its centre (m, rounded to mm), its label and where the label is."""

    position: tuple[float, float, float]
    label: str
    label_position: tuple[float, float, float]


class MapView:
    """Scene nodes under `/map`; toggles decide which layers are sent."""

    def __init__(self, server: viser.ViserServer, robot: RobotModel, mapping: MappingParams | None = None) -> None:
        """`mapping`: the map's tunables (its removal threshold colours the objects; default: the defaults)."""
        self.server = server
        self.robot = robot
        self.mapping = mapping or MappingParams()
        self.show = {"objects": True, "voxels": False, "edf": False, "spheres": False, "frusta": True,
                     "clouds": False}
        self._objects: dict[int, tuple[tuple, viser.BoxHandle | viser.PointCloudHandle, viser.LabelHandle]] = {}
        self._last_seen: dict[int, MappedObject] = {}
        self.names: dict[int, str] = {}
        """Operator-given names by map id (the Names tab, a sequence's `objects`), shown after '#id'."""
        self.fixed_labels: Callable[[], Sequence[FixedLabel]] = tuple
        """Labels other panels draw (the subtasks' goals, `AuthoringPanel.goal_labels`): the objects' keep clear."""
        self._layers: dict[str, viser.SceneNodeHandle] = {}
        sphere = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        self._sphere_mesh = (np.asarray(sphere.vertices, np.float32), np.asarray(sphere.faces, np.uint32))

    def set_layer(self, name: str, visible: bool) -> None:
        self.show[name] = visible
        if not visible:
            if name == "objects":
                self._clear_objects()
            handle = self._layers.pop(name, None)
            if handle is not None:
                handle.remove()

    def drawn_objects(self) -> dict[int, DrawnObject]:
        """The objects drawn now, by id (removed ones stay, grey and labelled, at their last known pose)."""
        return {i: DrawnObject(key[0], label.text, key[5]) for i, (key, _, label) in self._objects.items()}

    def _box_like(self, obj: MappedObject) -> bool:
        """Drawn as a box; objects longer than the map registers as movable boxes are drawn as their points."""
        return float(np.max(obj.extent[:2])) <= self.mapping.registration_max_extent_m or len(obj.points) == 0

    def _clear_objects(self) -> None:
        for _, box, label in self._objects.values():
            box.remove()
            label.remove()
        self._objects.clear()

    def update(self, snap: Snapshot) -> None:
        if self.show["objects"]:
            self._draw_objects(snap)
        if self.show["voxels"]:
            self._draw_points(snap)
        if self.show["edf"]:
            self._draw_edf(snap)
        if self.show["spheres"]:
            self._draw_spheres(snap)
        if self.show["frusta"]:
            self._draw_frusta(snap)
        if self.show["clouds"] and snap.clouds is not None and len(snap.clouds):
            colors = np.tile(np.array([[30, 160, 90]], np.uint8), (len(snap.clouds), 1))
            self._layers["clouds"] = self.server.scene.add_point_cloud(
                "/map/clouds", snap.clouds.astype(np.float32), colors, point_size=0.03, point_shape="circle")

    def _objects_to_draw(self, snap: Snapshot) -> list[tuple[MappedObject, bool]]:
        """Live objects, plus removed ones at their last known pose (the map keeps only their ids)."""
        objects = list(snap.object_map.objects) if snap.object_map is not None else []
        for obj in objects:
            self._last_seen[obj.id] = obj
        removed = set(snap.object_map.removed_ids) if snap.object_map is not None else set()
        live = {o.id for o in objects}
        out = [(o, o.status == ObjectStatus.REMOVED) for o in objects]
        out += [(self._last_seen[i], True) for i in sorted(removed - live) if i in self._last_seen]
        return out

    def _view(self) -> View | None:
        """The camera of the first browser on the page (labels are laid out for it), None without one."""
        clients = self.server.get_clients()
        return View.of(clients[min(clients)].camera) if clients else None

    def _draw_objects(self, snap: Snapshot) -> None:
        seen = set()
        self.names = operator_names(snap.anchors)
        if snap.object_map is None or not snap.object_map.objects and not snap.object_map.removed_ids:
            self._last_seen.clear()  # a new map (reset, another map kind)
        drawn = sorted(self._objects_to_draw(snap), key=lambda d: d[0].id)
        texts = [label_text(obj, removed, snap.state.t, self.names.get(obj.id)) for obj, removed in drawn]
        anchors = stacked([o.pose[:3, 3] + [0, 0, o.extent[2] / 2 + LABEL_LIFT_M] for o, _ in drawn])
        goals = self.fixed_labels()
        T_base = self.robot.frame_pose(snap.state.q, "mobile_base") if any(f.on_base for f in goals) else np.eye(4)
        fixed = [(f.world(T_base), f.text) for f in goals]
        anchors = screen_stacked(anchors, texts, self._view(), fixed)
        for (obj, removed), text, anchor in zip(drawn, texts, anchors, strict=True):
            seen.add(obj.id)
            self._draw_object(obj, removed, text, anchor)
        for obj_id in [i for i in self._objects if i not in seen]:
            _, box, label = self._objects.pop(obj_id)
            box.remove()
            label.remove()

    def _draw_object(self, obj: MappedObject, removed: bool, text: str, anchor: np.ndarray) -> None:
        """One object's box (or points) and its label at `anchor`; a label that only moved is moved, not re-sent."""
        key = (tuple(np.round(obj.pose[:3, 3], 3)), tuple(np.round(obj.extent, 3)), round(obj.consistency, 2),
               removed, text, tuple(np.round(anchor, 2)))
        old = self._objects.get(obj.id)
        if old is not None and old[0] == key:
            return
        if old is not None and old[0][:5] == key[:5]:
            old[2].position = anchor
            self._objects[obj.id] = (key, old[1], old[2])
            return
        if old is not None:
            old[1].remove()
            old[2].remove()
        color = (150, 150, 150) if removed else consistency_rgb(obj.consistency, self.mapping.theta_stat)
        if self._box_like(obj):
            box = self.server.scene.add_box(f"/map/objects/{obj.id}", color=color,
                                            dimensions=tuple(np.asarray(obj.extent) + 0.02), wireframe=True,
                                            position=obj.pose[:3, 3], wxyz=wxyz(obj.pose[:3, :3]))
        else:  # rows of shelves joined at corners: their bounding box would cover the corridor
            pts = np.asarray(obj.points, np.float32)[:: max(1, len(obj.points) // 800)]
            box = self.server.scene.add_point_cloud(f"/map/objects/{obj.id}", pts,
                                                    np.tile(np.array([color], np.uint8), (len(pts), 1)),
                                                    point_size=0.04, point_shape="square")
        label = self.server.scene.add_label(f"/map/labels/{obj.id}", text, position=anchor)
        self._objects[obj.id] = (key, box, label)

    def _draw_points(self, snap: Snapshot) -> None:
        pts = snap.map_points if snap.map_points is not None and len(snap.map_points) else np.zeros((1, 3))
        colors = np.tile(np.array([[90, 120, 220]], np.uint8), (len(pts), 1))
        self._layers["voxels"] = self.server.scene.add_point_cloud("/map/voxels", pts.astype(np.float32), colors,
                                                                   point_size=0.05, point_shape="square")

    def _draw_edf(self, snap: Snapshot) -> None:
        sl = snap.edf_slice
        if sl is None:
            return
        nx, ny = sl.values.shape
        gx, gy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        pts = np.column_stack([sl.origin[0] + sl.voxel * gx.ravel(), sl.origin[1] + sl.voxel * gy.ravel(),
                               np.full(gx.size, sl.z_m)])
        cutoff = float(np.nanmax(sl.values)) if sl.values.size else 1.0
        self._layers["edf"] = self.server.scene.add_point_cloud(
            "/map/edf_slice", pts.astype(np.float32), distance_rgb(sl.values.ravel(), cutoff),
            point_size=0.8 * sl.voxel, point_shape="square")

    def _draw_spheres(self, snap: Snapshot) -> None:
        centres = self.robot.sphere_centres(snap.state.q)
        v, f = self._sphere_mesh
        n = len(centres)
        self._layers["spheres"] = self.server.scene.add_batched_meshes_simple(
            "/map/spheres", v, f, batched_wxyzs=np.tile([1.0, 0, 0, 0], (n, 1)), batched_positions=centres,
            batched_scales=self.robot.sphere_radii, batched_colors=(80, 200, 255), batched_opacities=np.full(n, 0.35))

    def _draw_frusta(self, snap: Snapshot) -> None:
        for cam in self.robot.cameras:
            T = self.robot.camera_pose(snap.state.q, cam.name)
            name = f"frustum_{cam.name}"
            handle = self._layers.get(name)
            if handle is None:
                handle = self.server.scene.add_camera_frustum(f"/map/{name}", fov=math.radians(58.0), aspect=4 / 3,
                                                              scale=0.25, color=(30, 30, 30))
                self._layers[name] = handle
            handle.position = T[:3, 3]
            handle.wxyz = wxyz(T[:3, :3])
