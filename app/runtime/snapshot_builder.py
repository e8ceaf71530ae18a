"""Assemble the `Snapshot` the runtime publishes from a `ClosedLoop`: one consistent read of the run under
its lock, then the map under the map lock (never both at once), then the derived views (point clouds, EDF
slice, decimated map points). A map that raises still yields a snapshot (without map data), so the operator
always sees the state of the run, a fault included.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable

import numpy as np

from app.runtime.closed_loop import ClosedLoop, untrusted_notice
from app.runtime.snapshot import EDFSlice, RunState, Snapshot
from app.runtime.target_marks import target_marks
from core.types import DepthFrame, LocalEDF, ObjectMapSnapshot, Plan

log = logging.getLogger(__name__)

EDF_SLICE_Z_M = 0.3
MAP_POINTS_MAX = 20000
CLOUD_STRIDE_PX = 8
"""Every 8th pixel in u and v: about 1200 points per 320 × 240 frame, enough to see what a camera sees."""
RUN_STATE_HEADS = {RunState.ESTOP: "EMERGENCY STOP", RunState.PAUSED: "paused", RunState.IDLE: "idle",
                   RunState.FAULT: "FAULT"}


def status_line(run_state: RunState, sequence_status: str, plan: Plan | None, fault: str | None,
                localization: str | None = None) -> str:
    """One line for the operator: run state, the fault and its remedy, the sequencer's line, a controller
    that is not solving normally, a pose estimate the loop does not trust (`localization`, `untrusted_notice`)."""
    line = sequence_status
    if localization:
        line += f" · {localization}"
    if plan is not None and plan.status.value not in ("ok", "ok_with_slack"):
        line += f" · controller: {plan.status.value} {plan.message}"
    if fault is not None:
        line = f"{fault} (Reset to go on) · {line}"
    head = RUN_STATE_HEADS.get(run_state)
    return f"{head} · {line}" if head else line


def build_snapshot(loop: ClosedLoop, seq: int, messages: tuple[str, ...], sequence_version: int) -> Snapshot:
    """The state of everything in `loop` as one frozen value: the loop's published reading, then the map's."""
    r = loop.reading()
    object_map, points = _map_view(loop)
    world = loop.world
    untrusted = untrusted_notice(r.localization, r.config.htmpc.delta_safe_m)
    return Snapshot(
        seq=seq, wall_time=time.time(), state=r.state, run_state=r.run_state,
        status=status_line(r.run_state, r.view.status, r.plan, r.fault, untrusted),
        boxes=world.boxes() if world else (),
        plan=r.plan, base_path=r.view.path, object_map=object_map, map_points=points, edf_slice=edf_slice(r.edf),
        clouds=clouds(r.frames), progress=r.view.progress, active_index=r.view.index,
        sequence_version=sequence_version, min_distance_m=r.min_distance_m,
        collisions=len(world.collisions) if world else 0, timings_ms=r.timings_ms, map_kind=r.config.map_kind,
        constraint=r.config.constraint, speed=r.config.speed, messages=messages, fault=r.fault, command=r.command,
        depth_frames=r.frames, problems=loop.problems.counts(), targets=target_marks(r.sequence, r.view.progress),
        anchors=r.objects, base_estimate=r.base_estimate, base_true=r.base_true,
        localization=r.localization, pose_source=r.pose_source)


def _map_view(loop: ClosedLoop) -> tuple[ObjectMapSnapshot | None, np.ndarray | None]:
    try:
        with loop.using_map() as world_map:
            object_map = world_map.snapshot()
            points = world_map.occupied_points()
    except Exception as err:  # a broken map is a fault, and the snapshot goes out without it
        loop.fault(f"map snapshot: {type(err).__name__}: {err}")
        return None, None
    if len(points) > MAP_POINTS_MAX:
        points = points[:: int(math.ceil(len(points) / MAP_POINTS_MAX))]
    return object_map, points


def clouds(frames: Iterable[DepthFrame]) -> np.ndarray | None:
    """Decimated world points of each camera's latest frame, stacked."""
    from core.mapping import frame_points

    pts = [frame_points(f, stride=CLOUD_STRIDE_PX) for f in frames]
    return np.concatenate(pts) if pts else None


def edf_slice(edf: LocalEDF | None) -> EDFSlice | None:
    """The horizontal slice of the local EDF nearest `EDF_SLICE_Z_M`."""
    if edf is None:
        return None
    k = int(np.clip(round((EDF_SLICE_Z_M - edf.origin[2]) / edf.voxel), 0, edf.values.shape[2] - 1))
    return EDFSlice(origin=edf.origin[:2].copy(), voxel=edf.voxel, z_m=float(edf.origin[2] + k * edf.voxel),
                    values=edf.values[:, :, k].copy())
