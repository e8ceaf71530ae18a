"""Names and anchored targets in the studio: name a mapped object (click it in the 3D view, then *Name…*),
author "Reach its top" / "Approach its front" on it, and see each binding: the name in its object's label
('#4 box_3 E[v]=…', drawn by the map view; a scene box of the ground-truth map gets a label of its own), the
anchored goal's frame sitting on the object and moving with it, a line joining the two, and the list of
anchored subtasks ("2. pick: top of box_3 → #4"). Objects are listed by the one name they have everywhere ('#4').

A name may come with the object's full size (*Size (m)*, all 0: unknown): anchors on a box seen from one side
are then placed from the face seen and that size (docs/design.md, "Anchored targets").

It reads snapshots only (`Snapshot.anchors`, `object_map`, `progress`) and changes the run through the
runtime's public API (`name_object`, `set_sequence`)."""

from __future__ import annotations

import logging
import math

import numpy as np
import viser

from app.object_label import MAP_ID_PREFIX, map_id, object_id_of, shown_id
from app.runtime.snapshot import Snapshot
from app.target_check import check_targets
from app.ui.notify import notify_all
from tasks.schema import Anchor, BasePose, BaseSubtask, EEPose, EESubtask, Tolerance
from tasks.sequence_file import FileFormatError

log = logging.getLogger(__name__)

NONE: str = "(click an object)"
PICK_RGB = (90, 160, 230)
LINE_RGB = (240, 150, 30)
REACH_TOP = Anchor(object="x", face="top", offset=(-0.25, 0.0, 0.7), rpy_deg=(0.0, 90.0, 0.0))
"""The hand 0.7 m above the top, a quarter metre toward the front edge, pointing down (as in two_pickups)."""
APPROACH_FRONT = Anchor(object="x", face="front", offset=(-0.9, 0.0, 0.0), rpy_deg=(0.0, 0.0, 0.0))
"""The base 0.9 m in front of the front face (its clearance), facing the object."""


def mapped_objects(snap: Snapshot) -> dict[str, tuple[np.ndarray, np.ndarray, float]]:
    """Object id → (centre, extent, yaw) of what the map sees (with the ground-truth map, the scene boxes)."""
    if snap.object_map is not None and snap.object_map.objects:
        out = {}
        for o in snap.object_map.objects:
            R = o.pose[:3, :3]
            out[object_id_of(o.id)] = (o.pose[:3, 3], np.asarray(o.extent), float(np.arctan2(R[1, 0], R[0, 0])))
        return out
    if snap.map_kind == "ground_truth":
        return {b.id: (np.array(b.position), np.array(b.size), b.yaw) for b in snap.boxes}
    return {}


def binding_lines(snap: Snapshot) -> list[str]:
    """One line per anchored subtask: its goal on its object, and what the sequencer makes of it."""
    lines = []
    anchors = snap.anchors
    for p in snap.progress:
        name = p.anchor_object
        if name is None:
            continue
        obj = None if anchors is None else anchors.named(name)
        where = f" → {shown_id(obj.id)}" if obj is not None else ""
        if anchors is not None and obj is None:
            where = f" ({anchors.why_missing(name)})"
        lines.append(f"{p.index + 1}. {p.name}: {p.anchor_label}{where}")
    return lines


class AnchorPanel:
    """The 'Names' tab and the bindings drawn in the 3D view."""

    def __init__(self, server: viser.ViserServer, runtime) -> None:
        self.server, self.runtime = server, runtime
        gui = server.gui
        none: tuple[str, ...] = (NONE,)
        self.object = gui.add_dropdown("Object", options=none, initial_value=NONE)
        self.name = gui.add_text("Object name", initial_value="box_1")
        self.size = gui.add_vector3("Size (m)", (0.0, 0.0, 0.0), min=(0.0, 0.0, 0.0), step=0.05,
                                    hint="The object's full size along its x, y, z (all 0: unknown)")
        self.name_button = gui.add_button("Name…")
        self.reach_top = gui.add_button("Reach its top")
        self.approach_front = gui.add_button("Approach its front")
        self.bindings = gui.add_markdown("")
        self.name_button.on_click(lambda _: self._guarded(self.name_selected))
        self.reach_top.on_click(lambda _: self._guarded(lambda: self.add_anchored("reach", REACH_TOP)))
        self.approach_front.on_click(lambda _: self._guarded(lambda: self.add_anchored("approach", APPROACH_FRONT)))
        self._picks: dict[str, tuple[tuple, viser.BoxHandle]] = {}
        self._drawn: list = []
        self._drawn_key: tuple | None = None
        self._objects: dict[str, tuple[np.ndarray, np.ndarray, float]] = {}
        self._ids: dict[str, str] = {}
        """Dropdown entry ('#4') → object id (`object_4`)."""

    # --- actions ----------------------------------------------------------------------------------------

    def select(self, object_id: str) -> None:
        """A click on a mapped object in the 3D view (`object_id`: `object_4`, listed as '#4')."""
        shown = shown_id(object_id)
        self._ids[shown] = object_id
        if shown not in self.object.options:
            self.object.options = (*self.object.options, shown)
        self.object.value = shown

    def selected_id(self) -> str:
        """The id of the object the dropdown shows ('#4' → `object_4`; a scene box id as it is)."""
        shown = self.object.value
        return self._ids.get(shown, f"{MAP_ID_PREFIX}{shown[1:]}" if shown.startswith("#") else shown)

    def _offer(self) -> None:
        """The dropdown lists the objects mapped now by map id (and keeps the selection while it is mapped)."""
        self._ids = {shown_id(i): i for i in self._objects}
        ordered = sorted(self._objects, key=lambda i: (map_id(i) is None, map_id(i) or 0, i))
        options = (NONE, *(shown_id(i) for i in ordered))
        if tuple(self.object.options) != options:
            value = self.object.value
            self.object.options = options
            self.object.value = value if value in options else NONE

    def declared_size(self) -> tuple[float, float, float] | None:
        """The size typed in *Size (m)*: None when all 0 (unknown); ValueError unless every side is a number > 0."""
        size = tuple(float(v) for v in self.size.value)
        if all(v == 0.0 for v in size):
            return None
        if not all(math.isfinite(v) and v > 0.0 for v in size):
            raise ValueError(f"size {', '.join(f'{v:g}' for v in size)} m: every side a number > 0 (all 0: unknown)")
        return size[0], size[1], size[2]

    def name_selected(self) -> str:
        """Name the selected object with the size typed (`Runtime.name_object`); returns the name."""
        object_id, name = self.selected_id(), self.name.value.strip()
        self.runtime.name_object(name, object_id, self.declared_size())
        return name

    def add_anchored(self, what: str, template: Anchor) -> None:
        """Append a subtask anchored on the selected object (named first if it has no name yet)."""
        name = self._name_of(self.selected_id()) or self.name_selected()
        anchor = template.model_copy(update={"object": name})
        if template.face == "top":
            sub = EESubtask(name=f"{what} {describe_anchor(anchor)}", target=EEPose(anchor=anchor), dwell_s=1.0,
                            tolerance=Tolerance(position_m=0.03, orientation_deg=5.0), timeout_s=60.0)
        else:
            sub = BaseSubtask(name=f"{what} {describe_anchor(anchor)}", target=BasePose(anchor=anchor),
                              tolerance=Tolerance(position_m=0.15, orientation_deg=15.0), timeout_s=60.0)
        seq = self.runtime.sequence
        seq = seq.model_copy(update={"subtasks": [*seq.subtasks, sub]})
        check_targets(self.runtime, seq, scene_may_change=True, indices=[len(seq.subtasks) - 1])
        self.runtime.set_sequence(seq)

    def _name_of(self, object_id: str) -> str | None:
        anchors = getattr(self.runtime.closed_loop, "objects_view", None)
        return next((o.name for o in anchors.objects if o.id == object_id and o.name), None) if anchors else None

    def _guarded(self, action) -> None:
        try:
            action()
        except (ValueError, FileFormatError, RuntimeError, AttributeError) as err:
            notify_all(self.server, "Names", str(err))

    # --- drawing ----------------------------------------------------------------------------------------

    def update(self, snap: Snapshot) -> None:
        self._objects = mapped_objects(snap)
        self._draw_picks()
        self._offer()
        self._draw_bindings(snap)
        self.bindings.content = "\n".join(f"- {line}" for line in binding_lines(snap)) or "no anchored targets"

    def _draw_picks(self) -> None:
        """A clickable shell on every mapped object (the map's own drawing is not clickable)."""
        for oid in [i for i in self._picks if i not in self._objects]:
            self._picks.pop(oid)[1].remove()
        for oid, (centre, extent, yaw) in self._objects.items():
            key = (tuple(np.round(centre, 2)), tuple(np.round(extent, 2)), round(yaw, 2))
            old = self._picks.get(oid)
            if old is not None and old[0] == key:
                continue
            if old is not None:
                old[1].remove()
            handle = self.server.scene.add_box(f"/anchors/pick/{oid}", color=PICK_RGB, dimensions=tuple(extent + 0.04),
                                               opacity=0.12, position=centre, cast_shadow=False,
                                               wxyz=(np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)))
            handle.on_click(lambda _, oid=oid: self.select(oid))
            self._picks[oid] = (key, handle)

    def _draw_bindings(self, snap: Snapshot) -> None:
        """Names over scene boxes (a mapped object's name is in its map label), the anchored goals' frames on
        them, a line from each goal to its object."""
        anchors = snap.anchors
        named = [] if anchors is None else [o for o in anchors.objects if o.name and map_id(o.id) is None]
        goals = []
        for p in snap.progress:
            obj = None if anchors is None or p.anchor_object is None else anchors.named(p.anchor_object)
            if obj is not None and p.anchored_goal is not None:
                goals.append((p.index, np.array(p.anchored_goal), obj.position, obj.yaw))
        key = (tuple((o.name, tuple(np.round(o.position, 2))) for o in named),
               tuple((i, tuple(np.round(g, 2))) for i, g, _, _ in goals))
        if key == self._drawn_key:
            return
        self._drawn_key = key
        for handle in self._drawn:
            handle.remove()
        self._drawn = []
        scene = self.server.scene
        for o in named:
            self._drawn.append(scene.add_label(f"/anchors/names/{o.name}", o.name or "", anchor="bottom-center",
                                               position=o.position + [0, 0, o.extent[2] / 2 + 0.35]))
        for i, goal, _centre, yaw in goals:
            self._drawn.append(scene.add_frame(f"/anchors/goals/{i}", axes_length=0.2, axes_radius=0.01, position=goal,
                                               wxyz=(np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))))
        if goals:
            pts = np.array([[g, c] for _, g, c, _ in goals], np.float32)
            self._drawn.append(scene.add_line_segments("/anchors/lines", pts, LINE_RGB, thickness=0.015))


def describe_anchor(anchor: Anchor) -> str:
    return anchor.describe().split(" + ")[0]

