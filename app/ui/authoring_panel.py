"""Authoring the task sequence in the browser: a target gizmo, add base goals, waypoints and EE
targets, list, reorder, delete, edit tolerance/timeout/dwell/priority, rename, start anew, undo/redo,
YAML download and upload. Every change is checked (schema and `tasks.validation`) and goes to the
runtime as a new authored sequence.

viser runs GUI callbacks on a thread pool and the studio draws snapshots on the runtime's publishing
thread: one lock serialises everything that touches the panel's state and its scene nodes.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import viser
import viser.transforms as vtf

from app.recording.replay import ReplaySource
from app.runtime import Runtime
from app.runtime.snapshot import Snapshot
from app.ui.authoring import (
    PRIORITY_CHOICES,
    SequenceHistory,
    add_base_goal,
    add_base_waypoint,
    add_ee_target,
    delete_subtask,
    describe_change,
    follow_selection,
    move_subtask,
    replace_subtask,
)
from app.ui.label_layout import FixedLabel
from app.ui.notify import guarded, notify_all
from core.types import Vec3, vec3
from tasks.schema import BaseSubtask, EEPose, TaskSequence
from tasks.sequence_file import parse_sequence, sequence_to_yaml
from tasks.validation import Severity, TargetError, TargetFinding, changed_subtasks

NEXT_RUN = ("The run under way goes on with the sequence it started with (Start resumes it after Pause or Stop); "
            "this edit runs in the next run: Start after this one ends, or Reset.")
GOAL_LABEL_LIFT_M = 0.2
"""A subtask's label sits this far above its goal."""
NONE: str = "(none)"
"""The dropdown entry that selects nothing."""


def _rpy_deg(wxyz: np.ndarray) -> tuple[float, float, float]:
    R = vtf.SO3(np.asarray(wxyz)).as_matrix()
    pitch = math.asin(-float(np.clip(R[2, 0], -1.0, 1.0)))
    roll = math.atan2(R[2, 1], R[2, 2])
    yaw = math.atan2(R[1, 0], R[0, 0])
    return vec3(round(math.degrees(a), 2) for a in (roll, pitch, yaw))


def _label(i: int, sub) -> str:
    return f"{i + 1}. {sub.kind}: {sub.name}"


def _ee_marker(pose: EEPose) -> tuple[Vec3, np.ndarray]:
    """Where to draw an EE target: position and wxyz quaternion (identity when position only)."""
    R = pose.rotation()
    wxyz = np.array([1.0, 0.0, 0.0, 0.0]) if R is None else vtf.SO3.from_matrix(R).wxyz
    return pose.position, wxyz


class AuthoringPanel:
    """The 'Sequence' folder, the target gizmo `/authoring/target` and markers of every goal."""

    def __init__(self, server: viser.ViserServer, runtime: Runtime | ReplaySource) -> None:
        self.server, self.runtime = server, runtime
        self._lock = threading.RLock()
        self.history = SequenceHistory(runtime.sequence)
        self._version = runtime.sequence_version
        self._syncing = False
        self._markers: list = []
        self.goal_labels: list[FixedLabel] = []
        """The labels at the subtasks' goals, as the list names them ('4. ee: pick'); the map's labels keep clear."""
        g = guarded
        self.seq_name = server.gui.add_text("Sequence name", runtime.sequence.name)
        self.new_button = server.gui.add_button("New sequence", hint="Start an empty sequence (Undo brings it back)")
        self.target_pos = server.gui.add_vector3("Target (m)", (0.0, 0.0, 0.9), step=0.05)
        self.target_rpy = server.gui.add_vector3("Target rpy (deg)", (0.0, 0.0, 0.0), step=5.0)
        self.add_buttons = server.gui.add_button_group("Add at target", ("Base goal", "Waypoint", "EE target"))
        self.use_yaw = server.gui.add_checkbox("Base goal with heading", True)
        self.scene_may_change = server.gui.add_checkbox(
            "Scene changes before run", False,
            hint="Accept targets too close to a box today with a warning (you will move the box before they run)")
        self.select = server.gui.add_dropdown("Subtask", (NONE,), initial_value=NONE)
        self.name = server.gui.add_text("Name", "")
        self.pos_tol = server.gui.add_number("Position tolerance (m)", 0.1, min=0.001, step=0.01)
        self.ori_tol = server.gui.add_number("Orientation tolerance (deg)", 10.0, min=0.1, step=1.0)
        self.timeout = server.gui.add_number("Timeout (s)", 120.0, min=0.1, step=1.0)
        self.dwell = server.gui.add_number("Dwell (s)", 0.0, min=0.0, step=0.5)
        self.priority = server.gui.add_dropdown("Priority", tuple(PRIORITY_CHOICES), initial_value="default")
        self.edit_buttons = server.gui.add_button_group("Edit", ("Up", "Down", "Delete"))
        self.history_buttons = server.gui.add_button_group("History", ("Undo", "Redo"))
        self.download = server.gui.add_button("Download sequence (YAML)")
        self.upload = server.gui.add_upload_button("Load sequence (YAML)", mime_type="*/*")
        q = runtime.state.q
        self.target = server.scene.add_transform_controls(
            "/authoring/target", scale=0.5, position=(q[0] + 1.5 * math.cos(q[2]), q[1] + 1.5 * math.sin(q[2]), 0.9))
        self.target.on_update(lambda _: self._target_to_fields())
        self.target_pos.on_update(lambda _: self._fields_to_target())
        self.target_rpy.on_update(lambda _: self._fields_to_target())
        self._target_to_fields()
        self.seq_name.on_update(g(server, "rename sequence")(lambda _: self._rename()))
        self.new_button.on_click(g(server, "new sequence")(lambda _: self._new()))
        self.add_buttons.on_click(g(server, "add subtask")(lambda e: self._add(e.target.value)))
        self.select.on_update(lambda _: self._show_selected())
        for field in (self.name, self.pos_tol, self.ori_tol, self.timeout, self.dwell, self.priority):
            field.on_update(g(server, "edit subtask")(lambda _: self._edit_fields()))
        self.edit_buttons.on_click(g(server, "edit sequence")(lambda e: self._edit(e.target.value)))
        self.history_buttons.on_click(g(server, "history")(lambda e: self._history(e.target.value)))
        self.download.on_click(g(server, "download")(lambda e: self._download(e.client)))
        self.upload.on_upload(g(server, "load sequence")(lambda _: self._upload()))
        with self._lock:
            self._refresh()

    # --- helpers -----------------------------------------------------------------------------------

    @property
    def index(self) -> int | None:
        v = self.select.value
        return None if v == NONE else int(v.split(".", 1)[0]) - 1

    def _commit(self, seq: TaskSequence, select: int | None = None, text: str | None = None,
                source: str = "sequence") -> None:
        """Check the targets that changed, then make `seq` the authored sequence (caller holds the lock)."""
        warnings = self._apply(seq, select, changed_subtasks(self.history.current, seq), source=source, text=text)
        self.history.push(seq)
        for finding in warnings:
            notify_all(self.server, "Target accepted with a warning", str(finding), color="yellow")

    def _apply(self, seq: TaskSequence, select: int | None, indices: list[int] | None, source: str = "sequence",
               text: str | None = None) -> list[TargetFinding]:
        """Make `seq` the runtime's sequence; the runtime checks the targets of subtasks `indices` (None: all)."""
        warnings = self.runtime.set_sequence(seq, scene_may_change=self.scene_may_change.value, indices=indices,
                                             source=source, text=text)
        self._version = self.runtime.sequence_version
        self._refresh(seq, select)
        if getattr(self.runtime, "under_way", False):
            notify_all(self.server, "Applies to the next run", NEXT_RUN, color="yellow")
        return warnings

    def _refresh(self, seq: TaskSequence | None = None, select: int | None = None) -> None:
        seq = seq or self.history.current
        labels = tuple(_label(i, s) for i, s in enumerate(seq.subtasks))
        keep = self.index if select is None else select
        self._syncing = True
        try:
            self.select.options = (NONE, *labels)
            self.select.value = labels[keep] if keep is not None and 0 <= keep < len(labels) else NONE
            self.seq_name.value = seq.name
        finally:
            self._syncing = False
        self._show_selected(seq)
        self._draw_markers(seq)

    def _show_selected(self, seq: TaskSequence | None = None) -> None:
        with self._lock:
            seq = seq or self.history.current
            i = self.index
            if i is None or i >= len(seq.subtasks):
                return
            sub = seq.subtasks[i]
            self._syncing = True
            try:
                self.name.value = sub.name
                self.pos_tol.value = sub.tolerance.position_m
                self.ori_tol.value = sub.tolerance.orientation_deg
                self.timeout.value = sub.timeout_s
                self.dwell.value = sub.dwell_s
                self.priority.value = next((k for k, v in PRIORITY_CHOICES.items() if v == sub.priority), "default")
            finally:
                self._syncing = False

    def _draw_markers(self, seq: TaskSequence) -> None:
        """One frame per goal and waypoint, a label at each subtask's goal; base-frame EE targets are drawn
        under the robot's base frame, so they move with it. Anchored poses are relative to their object: the
        Names tab draws them where they sit on it (`AnchorPanel`), so none is drawn here at its raw offset."""
        for handle in self._markers:
            handle.remove()
        self._markers = []
        self.goal_labels = []
        scene = self.server.scene
        for i, sub in enumerate(seq.subtasks):
            poses = list(sub.path()) + ([sub.ee] if isinstance(sub, BaseSubtask) and sub.ee is not None else [])
            for k, pose in enumerate(poses):
                last = k == len(sub.path()) - 1
                if pose.anchor is not None:
                    continue
                if isinstance(pose, EEPose):
                    pos, wxyz = _ee_marker(pose)
                    color = (245, 140, 20)
                    on_base = pose.frame == "base"
                    parent = "/robot/mobile_base/authoring" if on_base else "/authoring/goals"
                else:
                    pos = (pose.x, pose.y, 0.02)
                    yaw = pose.yaw_rad or 0.0
                    wxyz = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
                    color = (40, 110, 240)
                    on_base, parent = False, "/authoring/goals"
                name = f"{parent}/{i}_{k}"
                self._markers.append(scene.add_frame(name, axes_length=0.25 if last else 0.12, axes_radius=0.012,
                                                     position=pos, wxyz=wxyz, origin_color=color))
                if last:
                    spot = FixedLabel(np.asarray(pos, float) + [0, 0, GOAL_LABEL_LIFT_M], _label(i, sub),
                                      on_base=on_base)
                    self.goal_labels.append(spot)
                    self._markers.append(scene.add_label(f"{name}_label", spot.text, position=spot.position))

    def _target_to_fields(self) -> None:
        if self._syncing:
            return
        self._syncing = True
        try:
            self.target_pos.value = vec3(round(float(v), 3) for v in self.target.position)
            self.target_rpy.value = _rpy_deg(self.target.wxyz)
        finally:
            self._syncing = False

    def _fields_to_target(self) -> None:
        if self._syncing:
            return
        self._syncing = True
        try:
            self.target.position = vec3(self.target_pos.value)
            r, p, y = np.radians(self.target_rpy.value)
            self.target.wxyz = vtf.SO3.from_rpy_radians(r, p, y).wxyz
        finally:
            self._syncing = False

    # --- actions ---------------------------------------------------------------------------------

    def _add(self, what: str) -> None:
        with self._lock:
            p = np.asarray(self.target.position, float)
            seq = self.history.current
            if what == "Base goal":
                yaw = _rpy_deg(self.target.wxyz)[2] if self.use_yaw.value else None
                new, select = add_base_goal(seq, float(p[0]), float(p[1]), yaw), len(seq.subtasks)
            elif what == "Waypoint":
                i = self.index
                if i is None:
                    raise ValueError("select the base subtask the waypoint belongs to")
                new, select = add_base_waypoint(seq, i, float(p[0]), float(p[1])), i
            else:
                new = add_ee_target(seq, vec3(p), _rpy_deg(self.target.wxyz))
                select = len(seq.subtasks)
            try:
                self._commit(new, select=select)
            except TargetError as err:
                raise ValueError(self._refusal(err.findings)) from err

    def _refusal(self, findings: list[TargetFinding]) -> str:
        """The reasons of a refused target; the target gizmo goes to the nearest acceptable value."""
        errors = [f for f in findings if f.severity == Severity.ERROR]
        nearest = next((f.nearest for f in errors if f.nearest is not None), None)
        text = "\n".join(str(f) for f in errors)
        if nearest is not None:
            z = float(self.target.position[2]) if len(nearest) == 2 else nearest[2]
            self.target.position = (nearest[0], nearest[1], z)
            self._target_to_fields()
            text += "\nThe target gizmo is there now: add again to accept it."
        return text

    def _edit_fields(self) -> None:
        with self._lock:
            i = self.index
            if self._syncing or i is None:
                return
            seq = replace_subtask(self.history.current, i, name=self.name.value,
                                  tolerance={"position_m": self.pos_tol.value, "orientation_deg": self.ori_tol.value},
                                  timeout_s=self.timeout.value, dwell_s=self.dwell.value,
                                  priority=PRIORITY_CHOICES[self.priority.value])
            self._commit(seq, select=i)

    def _edit(self, action: str) -> None:
        with self._lock:
            i = self.index
            if i is None:
                raise ValueError("select a subtask first")
            seq = self.history.current
            if action == "Delete":
                self._commit(delete_subtask(seq, i), select=min(i, len(seq.subtasks) - 2))
            else:
                delta = -1 if action == "Up" else 1
                self._commit(move_subtask(seq, i, delta), select=max(0, min(len(seq.subtasks) - 1, i + delta)))

    def _rename(self) -> None:
        with self._lock:
            if self._syncing or self.seq_name.value == self.history.current.name:
                return
            name = self.seq_name.value.strip() or "sequence"
            self._commit(self.history.current.model_copy(update={"name": name}))

    def _new(self) -> None:
        with self._lock:
            self._commit(TaskSequence(name="new sequence"))
        notify_all(self.server, "New sequence", "An empty sequence; Undo brings the previous one back.", color="blue")

    def _history(self, action: str) -> None:
        with self._lock:
            before = self.history.current
            seq = self.history.undo() if action == "Undo" else self.history.redo()
            if seq == before:
                raise ValueError(f"nothing to {action.lower()}")
            self._apply(seq, follow_selection(before, seq, self.index), [])  # checked when it was made
        notify_all(self.server, action, describe_change(before, seq), color="blue")

    def _download(self, client: viser.ClientHandle | None) -> None:
        (client or self.server).send_file_download("sequence.yaml", sequence_to_yaml(self.history.current).encode())

    def _upload(self) -> None:
        upload = self.upload.value
        text = upload.content.decode("utf-8", errors="replace")
        seq = parse_sequence(text, source=upload.name)
        with self._lock:
            warnings = self._apply(seq, 0 if seq.subtasks else None, None, source=upload.name, text=text)
            self.history.push(seq)
        for finding in warnings:
            notify_all(self.server, "Target accepted with a warning", str(finding), color="yellow")
        notify_all(self.server, "Sequence loaded", f"{upload.name}: {len(seq.subtasks)} subtasks", color="green")

    def update(self, snap: Snapshot) -> None:
        """Follow sequences set elsewhere (the bridge, a reset); snapshots older than our last edit are ignored."""
        with self._lock:
            if snap.sequence_version <= self._version:
                return
            self._version = snap.sequence_version
            self.history.push(self.runtime.sequence)
            self._refresh()
