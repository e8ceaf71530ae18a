"""Keyframes: the scans loop closures register against, each kept in its own node's frame.

A keyframe holds a registered frame's points above the floor that lay on a surface the map trusted (within
`keyframe_label_m`), in the base frame of its pose-graph node x_i, each with that object's id. Placed in the
world by the node's current value (x_i ∘ p), a keyframe moves when the graph is optimised: unlike the map's
surfaces, which stay where the drifting pose put them, the keyframes of a lap follow the loop closure that
corrects it. A keyframe is kept only where no other lies within `keyframe_step_m` and `keyframe_step_rad` (the
first visit of a place is the one kept; later visits close loops onto it).

Change: an object found disagreeing (moved) leaves every keyframe (`forget`); only objects the map trusts now enter
a submap, with the ids the map merged into them (a moved box re-created by POCD under a new id: the old id's points
stay out; a duplicate merged into another object is the same surface, and stays in).
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from dataclasses import dataclass

import numpy as np

from core.localization import se2
from core.localization.reference import FLOOR_ID, Reference, floor_grid


@dataclass
class Keyframe:
    """Node index, exposure time (s), points (N × 3, x-y in the node's base frame, z the height) and object ids."""

    node: int
    t: float
    points: np.ndarray
    ids: np.ndarray


class Keyframes:
    """The kept keyframes, their look-up by place, and the submap of the keyframes around an anchor."""

    def __init__(self, step_m: float, step_rad: float) -> None:
        self.step_m = step_m
        self.step_rad = step_rad
        self.frames: list[Keyframe] = []
        self.forgotten: set[int] = set()
        self.version = 0
        """Counts the changes of the kept points (a cache key)."""

    def covered(self, poses: np.ndarray, pose: np.ndarray) -> bool:
        """Whether a keyframe lies within `step_m` and `step_rad` of `pose` (poses: the graph's node values)."""
        return self._near(poses, pose, self.step_m, self.step_rad, None).size > 0

    def add(self, node: int, t: float, points_base: np.ndarray, ids: np.ndarray) -> None:
        keep = ~np.isin(ids, list(self.forgotten))
        self.frames.append(Keyframe(node, t, np.asarray(points_base[keep], float), np.asarray(ids[keep], int)))
        self.version += 1

    def forget(self, ids: Iterable[int]) -> None:
        """Objects found off their surface (moved): their points leave every keyframe for good."""
        ids = [i for i in ids if i not in self.forgotten]
        if not ids:
            return
        self.forgotten.update(ids)
        for k in self.frames:
            keep = ~np.isin(k.ids, ids)
            k.points, k.ids = k.points[keep], k.ids[keep]
        self.version += 1

    def anchor(self, poses: np.ndarray, pose: np.ndarray, t: float, min_age_s: float, search_m: float,
               search_rad: float) -> int | None:
        """The keyframe (index into `frames`) of an earlier visit (exposed at least `min_age_s` before t) nearest
        to `pose` within `search_m` and `search_rad`; None if there is none."""
        near = self._near(poses, pose, search_m, search_rad, t - min_age_s)
        if near.size == 0:
            return None
        d = [float(np.hypot(*(poses[self.frames[k].node, :2] - pose[:2]))) for k in near]
        return int(near[int(np.argmin(d))])

    def submap(self, poses: np.ndarray, anchor: int, t: float, min_age_s: float, radius_m: float,
               live_ids: Collection[int], voxel_m: float, centre_xy: np.ndarray, crop_m: float, floor_step_m: float
               ) -> tuple[Reference, tuple]:
        """The floor around `centre_xy` and the points of the keyframes of earlier visits (exposed at least
        `min_age_s` before t) within `radius_m` of the anchor's node, placed by the nodes' current values, objects
        not in `live_ids` left out, thinned to one point a `voxel_m` cell; and a key that changes when any of that
        changes (poses to 5 mm / 0.1°)."""
        centre = poses[self.frames[anchor].node]
        members = self._near(poses, centre, radius_m, np.inf, t - min_age_s)
        live = np.asarray(sorted(live_ids), int)
        parts, ids = [], []
        for k in members:
            f = self.frames[k]
            mine = np.isin(f.ids, live)
            if not mine.any():
                continue
            T = se2.to_matrix(poses[f.node])
            pts = f.points[mine]
            parts.append(pts @ T[:3, :3].T + T[:3, 3])
            ids.append(f.ids[mine])
        floor = floor_grid(centre_xy, crop_m, floor_step_m)
        key_poses = tuple(np.round(poses[[self.frames[k].node for k in members]] / [0.005, 0.005, 0.002]).astype(int)
                          .ravel().tolist())
        key = (tuple(members.tolist()), key_poses, self.version, tuple(live.tolist()),
               tuple(np.round(centre_xy / floor_step_m).astype(int).tolist()))
        if not parts:
            return Reference(floor, np.full(len(floor), FLOOR_ID)), key
        pts, pid = np.vstack(parts), np.concatenate(ids)
        _, first = np.unique(np.floor(pts / voxel_m).astype(np.int64), axis=0, return_index=True)
        first = np.sort(first)
        return Reference(np.vstack([floor, pts[first]]),
                         np.concatenate([np.full(len(floor), FLOOR_ID), pid[first]])), key

    def _near(self, poses: np.ndarray, pose: np.ndarray, dist_m: float, dist_rad: float, before_t: float | None
              ) -> np.ndarray:
        if not self.frames:
            return np.zeros(0, int)
        nodes = np.array([f.node for f in self.frames])
        xy = poses[nodes, :2]
        dyaw = np.abs((poses[nodes, 2] - pose[2] + np.pi) % (2 * np.pi) - np.pi)
        ok = (np.hypot(*(xy - pose[:2]).T) <= dist_m) & (dyaw <= dist_rad)
        if before_t is not None:
            ok &= np.array([f.t for f in self.frames]) <= before_t
        return np.flatnonzero(ok)
