"""The project's own topics of a studio recording (JSON messages, JSON schemas) and their snapshot mapping.

One published `Snapshot` becomes a handful of messages that share the MCAP `sequence` number (the
snapshot's index in the recording) and its log time (simulation time in lockstep, else wall clock; ns).
Beside these, `app.recording.foxglove_scene` writes the Foxglove channels the 3D panel draws (`/tf`, `/robot/model`,
`/scene/boxes`, `/map/objects`, `/plan/paths`, `/map/points`, `/camera/clouds`, `/camera/<name>/depth`).

| topic | schema | when |
| --- | --- | --- |
| `/robot/state` | `htmpc.RobotState` (t, q[9], v[9], base_estimate, base_true) | every snapshot |
| `/robot/command` | `htmpc.JointVelocityCommand` (t, qdot[9], the last command sent) | when known |
| `/plan` | `htmpc.Plan` (predicted q, v, u, Cartesian paths, task errors, solve times, status) | when a plan exists |
| `/map/posterior` | `htmpc.ObjectMap` (`#id name` label, pose, extent, E[v], posterior, status, seen) | object map |
| `/map/edf_slice` | `htmpc.EDFSlice` | when the controller has an EDF |
| `/sequence/progress` | `htmpc.Progress` (subtasks, active index, planned base path) | every snapshot |
| `/localization/health` | `htmpc.LocalizationHealth` (P, σ_xy, σ_yaw, verdicts, corrections) | localization |
| `/camera/<name>/info` | `htmpc.CameraInfo` (K, T_world_camera, range) | with each depth image |
| `/run/status` | `htmpc.RunStatus` (run state, status, clearance, timings, problems, messages) | every one, last |

`/run/status` is written last, so a snapshot is whole when its status message is present. JSON has no
NaN: non-finite numbers are written as null and read back as NaN.
"""

from __future__ import annotations

import math
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np

from app.object_label import object_label, operator_names
from app.runtime.problems import ProblemCount, ProblemKind
from app.runtime.snapshot import EDFSlice, RunState, Snapshot
from core.localization import LocalizationHealth
from core.scene import Box
from core.types import (
    DepthFrame,
    MappedObject,
    ObjectMapSnapshot,
    ObjectStatus,
    Plan,
    PlanReason,
    PlanStatus,
    Posterior,
    RobotState,
)
from tasks.sequencer import Blocked, GoalShift, Outcome, SubtaskProgress

FORMAT = "perceptive-htmpc-recording/3"
"""Written to the MCAP header's profile-independent metadata record `recording`."""
STATUS_TOPIC = "/run/status"

# --- JSON schemas (what Foxglove and other MCAP tools show as fields) -----------------------------------

_NUM = {"type": ["number", "null"]}
_INT = {"type": "integer"}
_STR = {"type": "string"}


def _arr(depth: int = 1) -> dict:
    schema: dict = _NUM
    for _ in range(depth):
        schema = {"type": ["array", "null"], "items": schema}
    return schema


def _obj(title: str, properties: dict[str, dict]) -> dict:
    return {"title": title, "type": "object", "properties": properties}


SCHEMAS: dict[str, dict] = {
    "htmpc.RobotState": _obj("robot state: q = [x, y, yaw, 6 arm joints] (m, rad), v their rates; base_estimate "
                             "the localizer's [x, y, yaw] (null without localization), base_true the simulator's "
                             "(null outside simulation)",
                             {"t": _NUM, "q": _arr(), "v": _arr(), "base_estimate": _arr(), "base_true": _arr()}),
    "htmpc.JointVelocityCommand": _obj("the last joint velocity command sent (base rates in the world frame)",
                                       {"t": _NUM, "qdot": _arr()}),
    "htmpc.Plan": _obj("HTMPC plan", {
        "t": _NUM, "dt": _NUM, "q": _arr(2), "v": _arr(2), "u": _arr(2), "base_path": _arr(2), "ee_path": _arr(2),
        "task_errors": _arr(), "solve_ms": _arr(), "status": _STR, "message": _STR, "reason": _STR,
        "min_h": _NUM}),
    "htmpc.ObjectMap": _obj("object-level map (POCD): consistency = E[v]", {
        "t": _NUM, "removed_ids": {"type": "array", "items": _INT},
        "objects": {"type": "array", "items": _obj("mapped object", {
            "id": _INT, "pose": _arr(2), "extent": _arr(), "status": _STR, "consistency": _NUM,
            "posterior": _obj("N(l | mu, sigma^2) Beta(v | alpha, beta)",
                              {"mu": _NUM, "sigma": _NUM, "alpha": _NUM, "beta": _NUM}),
            "observations": _INT, "label": _STR, "last_seen_t": _NUM})}}),
    "htmpc.EDFSlice": _obj("EDF slice at height z_m: values[i][j] at origin + voxel (i, j)",
                           {"origin": _arr(), "voxel": _NUM, "z_m": _NUM, "values": _arr(2)}),
    "htmpc.Progress": _obj("sequence progress", {
        "active_index": _INT, "sequence_version": _INT, "base_path": _arr(2),
        "subtasks": {"type": "array", "items": {"type": "object"}}}),
    "htmpc.RunStatus": _obj("run state, status line and measures of one snapshot", {
        "seq": _INT, "wall_time": _NUM, "t": _NUM, "run_state": _STR, "status": _STR, "min_distance_m": _NUM,
        "collisions": _INT, "timings_ms": {"type": "object"}, "map_kind": _STR, "constraint": _STR, "speed": _NUM,
        "messages": {"type": "array", "items": _STR}, "fault": {"type": ["string", "null"]}}),
    "htmpc.LocalizationHealth": _obj("the base pose estimate's health: covariance P (x, y in m, yaw in rad), stds, "
                                     "registration verdicts so far, age (s) and rate (1/s) of accepted corrections, "
                                     "why the pose is untrusted (null: trusted), the margin added to delta_safe (m)", {
        "t": _NUM, "covariance": _arr(2), "sigma_xy_m": _NUM, "sigma_yaw_rad": _NUM, "accepted": _INT,
        "rejected": _INT, "degenerate": _INT, "no_reference": _INT, "last_accepted_t": _NUM, "since_accepted_s": _NUM,
        "accepted_per_s": _NUM, "untrusted": {"type": ["string", "null"]}, "margin_growth_m": _NUM}),
    "htmpc.CameraInfo": _obj("depth camera: pinhole K (px), pose T_world_camera (OpenCV axes), range (m)",
                             {"t": _NUM, "camera": _STR, "K": _arr(2), "T_world_camera": _arr(2), "range_m": _NUM}),
}

FIXED_TOPICS: dict[str, str] = {
    "/robot/state": "htmpc.RobotState", "/robot/command": "htmpc.JointVelocityCommand", "/plan": "htmpc.Plan",
    "/map/posterior": "htmpc.ObjectMap", "/map/edf_slice": "htmpc.EDFSlice", "/sequence/progress": "htmpc.Progress",
    "/localization/health": "htmpc.LocalizationHealth", STATUS_TOPIC: "htmpc.RunStatus",
}


def depth_topics(camera: str) -> dict[str, str]:
    """The JSON topic of one depth camera (its image is `app.recording.foxglove_scene.depth_topic`) and its schema."""
    return {f"/camera/{camera}/info": "htmpc.CameraInfo"}


# --- values ↔ JSON ------------------------------------------------------------------------------------


def _num(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _list(a: Any, decimals: int = 5) -> list | None:
    """An array as nested lists, rounded; non-finite entries become None (JSON has no NaN)."""
    if a is None:
        return None
    a = np.round(np.asarray(a, dtype=float), decimals)
    if np.isfinite(a).all():
        return a.tolist()
    out = a.astype(object)
    out[~np.isfinite(a)] = None
    return out.tolist()


def _np(x: Any) -> np.ndarray:
    return np.array(x, dtype=float)  # None entries → NaN


def _np_or_none(x: Any) -> np.ndarray | None:
    return None if x is None else _np(x)


def _nan(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _record(obj: Any) -> dict:
    """A dataclass as a dict of its fields (numbers made JSON-safe, nested dataclasses as dicts)."""
    out = {}
    for f in fields(obj):
        value = getattr(obj, f.name)
        if is_dataclass(value):
            value = _record(value)
        out[f.name] = _num(value) if isinstance(value, float) else value
    return out


def _known(cls: type, data: dict) -> dict:
    """The entries of `data` that are fields of the dataclass `cls` (recordings stay readable as it grows)."""
    names = {f.name for f in fields(cls)}
    return {k: v for k, v in data.items() if k in names}


# --- snapshot → messages ------------------------------------------------------------------------------


def snapshot_messages(snap: Snapshot) -> list[tuple[str, dict]]:
    """The (topic, message) pairs of one snapshot's JSON topics, `/run/status` last."""
    t = snap.state.t
    out: list[tuple[str, dict]] = [("/robot/state", {"t": t, "q": _list(snap.state.q), "v": _list(snap.state.v),
                                                     "base_estimate": _list(snap.base_estimate),
                                                     "base_true": _list(snap.base_true)})]
    if snap.command is not None:
        out.append(("/robot/command", {"t": t, "qdot": _list(snap.command)}))
    if snap.plan is not None:
        p = snap.plan
        out.append(("/plan", {"t": p.t, "dt": p.dt, "q": _list(p.q), "v": _list(p.v), "u": _list(p.u),
                              "base_path": _list(p.base_path), "ee_path": _list(p.ee_path),
                              "task_errors": _list(p.task_errors), "solve_ms": _list(p.solve_ms),
                              "status": p.status.value, "message": p.message, "reason": p.reason.value,
                              "min_h": _num(p.min_h)}))
    if snap.object_map is not None:
        m, names = snap.object_map, operator_names(snap.anchors)
        out.append(("/map/posterior", {"t": m.t, "removed_ids": list(m.removed_ids), "objects": [
            {"id": o.id, "pose": _list(o.pose), "extent": _list(o.extent), "status": o.status.value,
             "consistency": _num(o.consistency), "posterior": _record(o.posterior), "observations": o.observations,
             "label": object_label(o.id, names.get(o.id)), "last_seen_t": _num(o.last_seen_t)}
            for o in m.objects]}))
    if snap.edf_slice is not None:
        e = snap.edf_slice
        out.append(("/map/edf_slice", {"origin": _list(e.origin), "voxel": e.voxel, "z_m": e.z_m,
                                       "values": _list(e.values, 3)}))
    if snap.localization is not None:
        h = snap.localization
        out.append(("/localization/health", {**_record(h), "covariance": _list(h.covariance)}))
    out.append(("/sequence/progress", {"active_index": snap.active_index, "sequence_version": snap.sequence_version,
                                       "base_path": _list(snap.base_path),
                                       "subtasks": [_record(p) for p in snap.progress]}))
    out.append((STATUS_TOPIC, {
        "seq": snap.seq, "wall_time": snap.wall_time, "t": t, "run_state": snap.run_state.value,
        "status": snap.status, "min_distance_m": _num(snap.min_distance_m), "collisions": snap.collisions,
        "timings_ms": {k: _num(v) for k, v in snap.timings_ms.items()}, "map_kind": snap.map_kind,
        "constraint": snap.constraint, "speed": snap.speed, "messages": list(snap.messages),
        "fault": getattr(snap, "fault", None), "problems": [_record(p) for p in snap.problems]}))
    return out


def depth_messages(frame: DepthFrame) -> list[tuple[str, dict]]:
    """A depth frame's camera info (its image goes on a Foxglove channel)."""
    return [(f"/camera/{frame.camera}/info", {"t": frame.t, "camera": frame.camera, "K": _list(frame.K, 9),
                                              "T_world_camera": _list(frame.T_world_camera, 9),
                                              "range_m": frame.range_m})]


# --- messages → snapshot ------------------------------------------------------------------------------


def _plan(p: dict) -> Plan:
    return Plan(t=p["t"], dt=p["dt"], q=_np(p["q"]), v=_np(p["v"]), u=_np(p["u"]), base_path=_np(p["base_path"]),
                ee_path=_np(p["ee_path"]), task_errors=tuple(map(_nan, p["task_errors"])),
                solve_ms=tuple(map(_nan, p["solve_ms"])), status=PlanStatus(p["status"]), message=p["message"],
                reason=PlanReason(p.get("reason", PlanReason.NONE.value)), min_h=_nan(p.get("min_h")))


def _object_map(m: dict) -> ObjectMapSnapshot:
    return ObjectMapSnapshot(t=m["t"], removed_ids=tuple(m["removed_ids"]), objects=tuple(
        MappedObject(id=o["id"], pose=_np(o["pose"]), extent=_np(o["extent"]), points=np.zeros((0, 3)),
                     posterior=Posterior(**{k: _nan(v) for k, v in o["posterior"].items()}),
                     status=ObjectStatus(o["status"]), observations=o["observations"],
                     last_seen_t=_nan(o.get("last_seen_t"))) for o in m["objects"]))


def _progress(p: dict) -> SubtaskProgress:
    values = _known(SubtaskProgress, p)
    values["outcome"] = Outcome(values["outcome"])
    for name in ("elapsed_s", "held_s", "position_error_m", "orientation_error_deg", "timeout_s"):
        if name in values:
            values[name] = _nan(values[name])
    if values.get("goal_shift") is not None:
        shift = values["goal_shift"]
        values["goal_shift"] = GoalShift(tuple(shift["original"]), tuple(shift["driven"]))
    if values.get("blocked") is not None:
        b = values["blocked"]
        values["blocked"] = Blocked(b["for_s"], None if b["obstacle_xy"] is None else tuple(b["obstacle_xy"]),
                                    _nan(b["obstacle_m"]))
    return SubtaskProgress(**values)


def _problem(p: dict) -> ProblemCount:
    return ProblemCount(kind=ProblemKind(p["kind"]), count=p["count"], first_t=_nan(p["first_t"]),
                        last_t=_nan(p["last_t"]), last_message=p["last_message"])


def snapshot_from_messages(messages: dict[str, dict]) -> Snapshot:
    """The snapshot whose messages (by topic) are given; `/run/status` and `/robot/state` must be among them."""
    run, state = messages[STATUS_TOPIC], messages["/robot/state"]
    edf, progress = messages.get("/map/edf_slice"), messages.get("/sequence/progress", {})
    command = messages.get("/robot/command")
    return Snapshot(**_known(Snapshot, dict(
        seq=run["seq"], wall_time=run["wall_time"], state=RobotState(state["t"], _np(state["q"]), _np(state["v"])),
        run_state=RunState(run["run_state"]), status=run["status"],
        boxes=tuple(Box(b["id"], tuple(b["position"]), tuple(b["size"]), b["yaw"], b.get("dark", False))
                    for b in messages.get("/scene/boxes", {}).get("boxes", [])),
        plan=_plan(messages["/plan"]) if "/plan" in messages else None,
        base_path=_np_or_none(progress.get("base_path")),
        object_map=_object_map(messages["/map/posterior"]) if "/map/posterior" in messages else None,
        map_points=_np(messages["/map/points"]["points"]) if "/map/points" in messages else None,
        clouds=_np(messages["/camera/clouds"]["points"]) if "/camera/clouds" in messages else None,
        edf_slice=None if edf is None else EDFSlice(_np(edf["origin"]), edf["voxel"], edf["z_m"], _np(edf["values"])),
        progress=tuple(_progress(p) for p in progress.get("subtasks", [])),
        active_index=progress.get("active_index", -1), sequence_version=progress.get("sequence_version", 0),
        min_distance_m=_nan(run["min_distance_m"]), collisions=run["collisions"],
        timings_ms={k: _nan(v) for k, v in run["timings_ms"].items()}, map_kind=run["map_kind"],
        constraint=run["constraint"], speed=run["speed"],
        command=None if command is None else _np(command["qdot"]), fault=run.get("fault"),
        problems=tuple(_problem(p) for p in run.get("problems", ())),
        base_estimate=_np_or_none(state.get("base_estimate")), base_true=_np_or_none(state.get("base_true")),
        localization=_health(messages["/localization/health"]) if "/localization/health" in messages else None)))


def _health(h: dict) -> LocalizationHealth:
    return LocalizationHealth(**{**_known(LocalizationHealth, h), "covariance": _np(h["covariance"]),
                                 "last_accepted_t": h.get("last_accepted_t")})


def depth_frame_from_messages(depth: np.ndarray, info: dict) -> DepthFrame:
    """The depth frame of a `/camera/<name>/depth` image (H×W metres) and its `/camera/<name>/info`."""
    return DepthFrame(t=info["t"], camera=info["camera"], depth=depth.astype(np.float32), K=_np(info["K"]),
                      T_world_camera=_np(info["T_world_camera"]), range_m=info["range_m"])
