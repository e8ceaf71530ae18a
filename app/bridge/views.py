"""Runtime data (snapshots, plans, scenes, link counters) as the operator API's response models.

JSON has no NaN: every non-finite number becomes None.
"""

from __future__ import annotations

import numpy as np

from app.bridge.attachment import RuntimeAttachment
from app.bridge.protocol import (
    BoxOut,
    Health,
    LinkCounters,
    LocalizationOut,
    LocalizedBy,
    MappedObjectOut,
    ObjectsOut,
    PlanOut,
    ProgressOut,
    RobotStateOut,
    SceneOut,
    SubtaskProgressOut,
    finite_or_none,
)
from app.bridge.robot_link import RobotLink
from app.object_label import object_id_of, shown_id
from app.runtime.snapshot import Snapshot
from core.scene import Scene
from core.types import Plan, PoseSource
from tasks.sequencer import SubtaskProgress


def json_array(a: np.ndarray) -> list:
    """Nested lists of floats with None for NaN/inf (a plan's arrays: one or more dimensions)."""
    a = np.asarray(a, dtype=float)
    return [json_array(row) for row in a] if a.ndim > 1 else [finite_or_none(float(x)) for x in a]


def localized_by(localizing: bool, pose_source: PoseSource) -> LocalizedBy:
    """Who localizes the pose the runtime uses: its localizer, the driver (a pose it localized itself), nobody."""
    return "localizer" if localizing else "driver" if pose_source == PoseSource.LOCALIZED else "off"


def localization_out(snap: Snapshot) -> LocalizationOut:
    h = snap.localization
    if h is None:
        return LocalizationOut(by=localized_by(False, snap.pose_source))
    return LocalizationOut(by="localizer", accepted=h.accepted, rejected=h.rejected, degenerate=h.degenerate,
                           no_reference=h.no_reference, sigma_xy_m=finite_or_none(h.sigma_xy_m),
                           since_accepted_s=finite_or_none(h.since_accepted_s), untrusted=h.untrusted)


def state_out(snap: Snapshot) -> RobotStateOut:
    s = snap.state
    return RobotStateOut(t=s.t, q=[float(x) for x in s.q], v=[float(x) for x in s.v],
                         run_state=snap.run_state.value, status=snap.status, fault=snap.fault,
                         pose_source=snap.pose_source.value, localization=localization_out(snap))


def plan_out(plan: Plan) -> PlanOut:
    return PlanOut(t=plan.t, dt=plan.dt, q=json_array(plan.q), v=json_array(plan.v), u=json_array(plan.u),
                   base_path=json_array(plan.base_path), ee_path=json_array(plan.ee_path),
                   task_errors=json_array(np.asarray(plan.task_errors, dtype=float).reshape(-1)),
                   solve_ms=json_array(np.asarray(plan.solve_ms, dtype=float).reshape(-1)),
                   status=plan.status.value, message=plan.message, reason=plan.reason.value,
                   min_h=finite_or_none(plan.min_h))


def _subtask_out(p: SubtaskProgress) -> SubtaskProgressOut:
    return SubtaskProgressOut(index=p.index, name=p.name, kind=p.kind, outcome=p.outcome.value,
                              elapsed_s=finite_or_none(p.elapsed_s), held_s=finite_or_none(p.held_s),
                              position_error_m=finite_or_none(p.position_error_m),
                              orientation_error_deg=finite_or_none(p.orientation_error_deg), message=p.message,
                              no_path=p.no_path, blocked=p.blocked is not None, anchor_object=p.anchor_object,
                              anchor=p.anchor_label,
                              anchored_goal=None if p.anchored_goal is None else [float(v) for v in p.anchored_goal])


def progress_out(snap: Snapshot) -> ProgressOut:
    return ProgressOut(run_state=snap.run_state.value, status=snap.status, active_index=snap.active_index,
                       subtasks=[_subtask_out(p) for p in snap.progress])


def scene_out(scene: Scene) -> SceneOut:
    boxes = [BoxOut(id=b.id, position=list(b.position), size=list(b.size), yaw=b.yaw) for b in scene.boxes]
    return SceneOut(name=scene.name, robot_start=list(scene.robot_start), boxes=boxes)


def health_out(link: RobotLink, attachment: RuntimeAttachment | None) -> Health:
    rtt = np.asarray(link.rtt_ms())
    age = link.state_age_s()
    last = link.last_command
    counters = LinkCounters(
        states=link.counts["states"], frames=link.counts["frames"], frames_dropped=link.counts["frames_dropped"],
        commands_sent=link.counts["commands_sent"], commands_superseded=link.counts["commands_superseded"],
        acks=link.counts["acks"], rejected=dict(link.rejected), stale_events=link.counts["stale_events"])
    return Health(
        driver_connected=link.connected, driver=link.driver if link.connected else None,
        state_age_ms=finite_or_none(age * 1e3), stale=link.is_stale(),
        hold=None if last is None or last.reason == "runtime" else last.reason,
        runtime_attached=attachment is not None,
        run_state=None if attachment is None else attachment.runtime.run_state.value, counters=counters,
        command_rtt_median_ms=finite_or_none(float(np.median(rtt))) if rtt.size else None,
        command_rtt_p99_ms=finite_or_none(float(np.percentile(rtt, 99))) if rtt.size else None,
        pose_source=None if link.pose_source is None else link.pose_source.value,
        localized_by=None if attachment is None else localized_by(attachment.runtime.closed_loop.localizing,
                                                                   attachment.runtime.closed_loop.pose_source))


def objects_out(snap: Snapshot) -> ObjectsOut:
    """The map's live objects (with the ground-truth map, the scene boxes) with their names, as `/api/objects`
    lists them."""
    views = {} if snap.anchors is None else {o.id: o for o in snap.anchors.objects}
    found: list[tuple[str, np.ndarray, float, np.ndarray, float, str]] = []
    if snap.map_kind == "ground_truth":
        found = [(b.id, np.asarray(b.position), b.yaw, np.asarray(b.size), 1.0, "active") for b in snap.boxes]
    elif snap.object_map is not None:
        for o in snap.object_map.objects:
            R = o.pose[:3, :3]
            found.append((object_id_of(o.id), o.pose[:3, 3], float(np.arctan2(R[1, 0], R[0, 0])), o.extent,
                          o.consistency, o.status.value))
    objects = []
    for oid, position, yaw, extent, consistency, state in found:
        view = views.get(oid)
        size = None if view is None or view.size is None else json_array(view.size)
        objects.append(MappedObjectOut(id=oid, label=shown_id(oid), name=None if view is None else view.name,
                                       position=[float(v) for v in position], yaw_deg=float(np.degrees(yaw)),
                                       extent=[float(v) for v in extent], consistency=float(consistency), status=state,
                                       size=size))
    unresolved = {} if snap.anchors is None else dict(snap.anchors.unresolved)
    return ObjectsOut(t=snap.state.t, map_kind=snap.map_kind, objects=objects, unresolved=unresolved)
