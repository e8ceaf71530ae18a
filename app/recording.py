"""Record a run's snapshots to a file and read them back for replay in the studio.

Format: gzip-compressed JSON Lines, one snapshot a line (numbers as lists), with a header line
naming the format version. Map points are kept every `points_every`-th snapshot to stay small.
"""

from __future__ import annotations

import gzip
import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from app.snapshot import EDFSlice, RunState, Snapshot
from core.sim.scene import Box
from core.types import MappedObject, ObjectMapSnapshot, ObjectStatus, Plan, PlanStatus, Posterior, RobotState
from tasks.sequencer import Outcome, SubtaskProgress

FORMAT = "perceptive-htmpc-recording/1"


def _arr(a) -> list | None:
    return None if a is None else np.asarray(a, float).round(5).tolist()


def snapshot_to_dict(snap: Snapshot, with_points: bool = True) -> dict:
    plan = snap.plan
    return {
        "seq": snap.seq, "wall_time": snap.wall_time, "t": snap.state.t,
        "q": _arr(snap.state.q), "v": _arr(snap.state.v),
        "run_state": snap.run_state.value, "status": snap.status,
        "boxes": [[b.id, list(b.position), list(b.size), b.yaw] for b in snap.boxes],
        "plan": None if plan is None else {
            "t": plan.t, "dt": plan.dt, "q": _arr(plan.q), "v": _arr(plan.v), "u": _arr(plan.u),
            "base_path": _arr(plan.base_path), "ee_path": _arr(plan.ee_path), "task_errors": list(plan.task_errors),
            "solve_ms": list(plan.solve_ms), "status": plan.status.value, "message": plan.message},
        "base_path": _arr(snap.base_path),
        "objects": None if snap.object_map is None else [
            {"id": o.id, "pose": _arr(o.pose), "extent": _arr(o.extent), "status": o.status.value,
             "posterior": [o.posterior.mu, o.posterior.sigma, o.posterior.alpha, o.posterior.beta],
             "observations": o.observations} for o in snap.object_map.objects],
        "removed_ids": [] if snap.object_map is None else list(snap.object_map.removed_ids),
        "map_points": _arr(snap.map_points) if with_points else None,
        "clouds": _arr(snap.clouds) if with_points else None,
        "edf_slice": None if snap.edf_slice is None else {
            "origin": _arr(snap.edf_slice.origin), "voxel": snap.edf_slice.voxel, "z_m": snap.edf_slice.z_m,
            "values": _arr(snap.edf_slice.values)},
        "progress": [{"index": p.index, "name": p.name, "kind": p.kind, "outcome": p.outcome.value,
                      "elapsed_s": p.elapsed_s, "held_s": p.held_s, "position_error_m": p.position_error_m,
                      "orientation_error_deg": p.orientation_error_deg, "message": p.message} for p in snap.progress],
        "active_index": snap.active_index, "sequence_version": snap.sequence_version,
        "min_distance_m": snap.min_distance_m, "collisions": snap.collisions, "timings_ms": snap.timings_ms,
        "map_kind": snap.map_kind, "constraint": snap.constraint, "speed": snap.speed,
    }


def _np(x) -> np.ndarray | None:
    return None if x is None else np.asarray(x, float)


def snapshot_from_dict(d: dict) -> Snapshot:
    p = d["plan"]
    plan = None if p is None else Plan(
        t=p["t"], dt=p["dt"], q=_np(p["q"]), v=_np(p["v"]), u=_np(p["u"]), base_path=_np(p["base_path"]),
        ee_path=_np(p["ee_path"]), task_errors=tuple(p["task_errors"]), solve_ms=tuple(p["solve_ms"]),
        status=PlanStatus(p["status"]), message=p["message"])
    objects = None if d["objects"] is None else ObjectMapSnapshot(
        t=d["t"], removed_ids=tuple(d["removed_ids"]),
        objects=tuple(MappedObject(id=o["id"], pose=_np(o["pose"]), extent=_np(o["extent"]), points=np.zeros((0, 3)),
                                   posterior=Posterior(*o["posterior"]), status=ObjectStatus(o["status"]),
                                   observations=o["observations"]) for o in d["objects"]))
    e = d["edf_slice"]
    return Snapshot(
        seq=d["seq"], wall_time=d["wall_time"], state=RobotState(d["t"], _np(d["q"]), _np(d["v"])),
        run_state=RunState(d["run_state"]), status=d["status"],
        boxes=tuple(Box(i, tuple(pos), tuple(size), yaw) for i, pos, size, yaw in d["boxes"]), plan=plan,
        base_path=_np(d["base_path"]), object_map=objects, map_points=_np(d["map_points"]),
        clouds=_np(d.get("clouds")),
        edf_slice=None if e is None else EDFSlice(_np(e["origin"]), e["voxel"], e["z_m"], _np(e["values"])),
        progress=tuple(SubtaskProgress(p["index"], p["name"], p["kind"], Outcome(p["outcome"]), p["elapsed_s"],
                                       p["held_s"], p["position_error_m"], p["orientation_error_deg"], p["message"])
                       for p in d["progress"]),
        active_index=d["active_index"], sequence_version=d["sequence_version"], min_distance_m=d["min_distance_m"],
        collisions=d["collisions"], timings_ms=d["timings_ms"], map_kind=d["map_kind"], constraint=d["constraint"],
        speed=d["speed"])


class Recorder:
    """Subscriber that appends every snapshot to a recording file."""

    def __init__(self, path: Path, points_every: int = 10) -> None:
        self.path = Path(path)
        self.points_every = points_every
        self.count = 0
        self._file = gzip.open(self.path, "wt", encoding="utf-8")  # noqa: SIM115 (open for the recorder's life)
        self._file.write(json.dumps({"format": FORMAT}) + "\n")

    def __call__(self, snap: Snapshot) -> None:
        line = json.dumps(snapshot_to_dict(snap, with_points=self.count % self.points_every == 0), allow_nan=True)
        self._file.write(line + "\n")
        self.count += 1

    def close(self) -> None:
        self._file.close()


def read_recording(path: Path) -> Iterator[Snapshot]:
    """Snapshots of a recording file, in order; a file of another kind raises ValueError."""
    with gzip.open(Path(path), "rt", encoding="utf-8") as f:
        header = json.loads(f.readline() or "{}")
        if header.get("format") != FORMAT:
            raise ValueError(f"{path} is not a studio recording (expected format {FORMAT})")
        for line in f:
            if line.strip():
                yield snapshot_from_dict(json.loads(line))
