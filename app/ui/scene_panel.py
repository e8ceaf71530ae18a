"""Scene edits while the robot runs: select a box (list or click), drag it with a gizmo or type its
pose and apply it, add, delete, randomise (the paper's generator), save and load scene files.

Typed values only move the gizmo (a preview) until 'Move to typed pose': applied field by field, x then y
put the box through an in-between pose the operator never asked for. The gizmo floats above the box: at its
centre the box hid its handles and a drag turned the camera instead."""

from __future__ import annotations

import math

import numpy as np
import viser

from app.recording.replay import ReplaySource
from app.runtime import Runtime
from app.runtime.snapshot import Snapshot
from app.ui.notify import guarded, notify_all
from core.scene import Box, parse_scene, scene_to_yaml
from core.types import vec3

NONE: str = "(none)"
"""The dropdown entry that selects nothing."""
GIZMO_LIFT_M = 0.15
"""The gizmo sits this far above the top of the selected box."""


def _yaw_of(wxyz: np.ndarray) -> float:
    w, x, y, z = wxyz
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class ScenePanel:
    """The 'Scene' folder and the box gizmo under `/scene/gizmo`."""

    def __init__(self, server: viser.ViserServer, runtime: Runtime | ReplaySource) -> None:
        self.server, self.runtime = server, runtime
        self._box_ids: tuple[str, ...] = ()
        self._boxes: dict[str, Box] = {b.id: b for b in runtime.snapshot().boxes}
        self._syncing = False
        self._counter = 0
        g = guarded
        self.select = server.gui.add_dropdown("Box", (NONE,), initial_value=NONE)
        self.position = server.gui.add_vector3("Position (m)", (0.0, 0.0, 0.3), step=0.05)
        self.yaw = server.gui.add_number("Yaw (deg)", 0.0, step=5.0)
        self.size = server.gui.add_vector3("New box size (m)", (0.6, 0.6, 0.6), min=(0.05, 0.05, 0.05), step=0.05)
        self.apply = server.gui.add_button("Move to typed pose", hint="Move the selected box to the pose typed above")
        self.actions = server.gui.add_button_group("Box", ("Add", "Delete"))
        self.seed = server.gui.add_number("Random seed", 0, step=1)
        self.randomise = server.gui.add_button("Randomise scene (paper)")
        self.save = server.gui.add_button("Save scene (YAML)")
        self.load = server.gui.add_upload_button("Load scene (YAML)", mime_type="*/*")
        self.gizmo = server.scene.add_transform_controls("/scene/gizmo", scale=0.6, visible=False,
                                                         active_axes=(True, True, False), disable_sliders=False,
                                                         depth_test=False)
        self.select.on_update(lambda _: self._on_select())
        self.gizmo.on_update(g(server, "move box")(lambda _: self._on_gizmo()))
        self.position.on_update(lambda _: self._preview_typed())
        self.yaw.on_update(lambda _: self._preview_typed())
        self.apply.on_click(g(server, "move box")(lambda _: self._on_typed()))
        self.actions.on_click(g(server, "edit scene")(lambda e: self._on_action(e.target.value)))
        self.randomise.on_click(g(server, "randomise")(lambda _: runtime.randomise_scene(int(self.seed.value))))
        self.save.on_click(g(server, "save scene")(lambda e: self._download(e.client)))
        self.load.on_upload(g(server, "load scene")(lambda _: self._upload()))

    @property
    def selected(self) -> str | None:
        return None if self.select.value == NONE else self.select.value

    def select_box(self, box_id: str) -> None:
        """Select a box (e.g. clicked in the 3D view)."""
        if box_id in self._box_ids:
            self.select.value = box_id

    def _on_select(self) -> None:
        box_id = self.selected
        self.gizmo.visible = box_id is not None
        if box_id is None:
            return
        self._show_pose(self._boxes[box_id], move_gizmo=True)

    def _lift(self, box_id: str) -> np.ndarray:
        """Gizmo position minus box centre: straight up to above the box's top."""
        box = self._boxes.get(box_id)
        return np.array([0.0, 0.0, (box.size[2] / 2 if box else 0.3) + GIZMO_LIFT_M])

    def _on_gizmo(self) -> None:
        if self._syncing or self.selected is None:
            return
        centre = np.asarray(self.gizmo.position) - self._lift(self.selected)
        box = self.runtime.move_box(self.selected, vec3(centre),
                                    _yaw_of(np.asarray(self.gizmo.wxyz)))
        self._boxes[box.id] = box
        self._show_pose(box, move_gizmo=False)  # the gizmo is where the user drags it

    def _place_gizmo(self, position, yaw: float, box_id: str) -> None:
        self.gizmo.position = tuple(np.asarray(position, float) + self._lift(box_id))
        self.gizmo.wxyz = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))

    def _show_pose(self, box: Box, move_gizmo: bool) -> None:
        """Show the box's pose in the typed fields (and on the gizmo) without firing their callbacks."""
        self._syncing = True
        try:
            if move_gizmo:
                self._place_gizmo(box.position, box.yaw, box.id)
            self.position.value = box.position
            self.yaw.value = round(math.degrees(box.yaw), 2)
        finally:
            self._syncing = False

    def _preview_typed(self) -> None:
        """Typed values move the gizmo only; the box moves on 'Move to typed pose'."""
        if self._syncing or self.selected is None:
            return
        self._syncing = True
        try:
            self._place_gizmo(self.position.value, math.radians(self.yaw.value), self.selected)
        finally:
            self._syncing = False

    def _on_typed(self) -> None:
        if self.selected is None:
            raise ValueError("select a box first")
        try:
            box = self.runtime.move_box(self.selected, vec3(self.position.value), math.radians(self.yaw.value))
            self._boxes[box.id] = box
        finally:
            self._on_select()  # show where the box really is (unchanged if the move was refused)

    def _on_action(self, action: str) -> None:
        if action == "Add":
            q = self.runtime.state.q
            size = vec3(self.size.value)
            ahead = vec3((q[0] + 2.0 * math.cos(q[2]), q[1] + 2.0 * math.sin(q[2]), size[2] / 2))
            self._counter += 1
            box_id = f"new_{self._counter}"
            while box_id in self._box_ids:
                self._counter += 1
                box_id = f"new_{self._counter}"
            box = Box(box_id, ahead, size, float(q[2]))
            self.runtime.add_box(box)
            self._boxes[box_id] = box
            self._refresh(tuple(self._boxes.values()))
            self.select.value = box_id
        elif action == "Delete":
            if self.selected is None:
                raise ValueError("select a box first")
            self.runtime.remove_box(self.selected)
            self._boxes.pop(self.selected, None)
            self._refresh(tuple(self._boxes.values()))
            self.select.value = NONE

    def _download(self, client: viser.ClientHandle | None) -> None:
        content = scene_to_yaml(self.runtime.scene()).encode()
        (client or self.server).send_file_download("scene.yaml", content)

    def _upload(self) -> None:
        upload = self.load.value
        scene = parse_scene(upload.content.decode("utf-8", errors="replace"), source=upload.name)
        self.runtime.reset(scene)
        notify_all(self.server, "Scene loaded", f"{upload.name}: {len(scene.boxes)} boxes", color="green")

    def _refresh(self, boxes: tuple[Box, ...]) -> None:
        ids = tuple(sorted(b.id for b in boxes))
        if ids != self._box_ids:
            self._box_ids = ids
            current = self.select.value
            self.select.options = (NONE, *ids)
            if current not in ids:
                self.select.value = NONE

    def update(self, snap: Snapshot) -> None:
        self._boxes = {b.id: b for b in snap.boxes}
        self._refresh(snap.boxes)
