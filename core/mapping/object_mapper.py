"""The object-level map (POCD, METHOD.md "Perception and mapping"): depth frames in, objects out.

Per depth frame:

1. points: unproject (every `pixel_stride`-th pixel, range cut-off), drop the floor and the robot
   (`scene_points.py`);
2. segmentation: 5 cm voxels, 26-connected clusters of at least `min_segment_voxels` (`segmentation.py`);
3. association: cost = truncated mean distance of a segment's (sampled) voxels to the object, i.e. to
   its submap surface M_i or its fitted box's faces, whichever is nearer; Hungarian with a gate; a
   second segment lying on a matched object (an occluder split it) joins it (`association.py`);
4. registration: when a fifth of a matched segment lies off the object, point-to-plane ICP moves the
   object (a box pushed 20–50 cm keeps its id at its new pose; farther moves are a new object and the
   old one goes by step 5) (`registration.py`);
5. consistency: a matched object is updated by Delta = mean M_i at the observed points within its box
   grown by tau (new surface revealed elsewhere is no change), its submap grows, and every third
   observation its voxels seen through are counted, those seen through three times running carved;
   an unmatched object whose expected-visible surface was seen through is a forced outlier
   (`visibility.py`, `consistency.py`); unseen or occluded objects keep their belief; an object with
   E[v] < theta_stat after more than `min_observations` updates is removed;
6. new objects: unmatched segments, with the prior (alpha0, beta0, mu0, sigma0), largest first; a
   segment lying on an object created in the same frame joins it.

Update rate, cap and evidence weighting (our choice next to POCD's)
-------------------------------------------------------------------
POCD updates once per frame, caps alpha and beta at 25 and counts a forced outlier as one outlier.
From a saturated belief (a box seen for a few seconds) that takes about 35 frames of a clear view of
the empty place to fall under 0.4 (METHOD.md; `tests/core/mapping/test_map_consistency.py` reproduces
3, 6 and 35 for boxes seen 1, 3 and 30 times). We keep one update per depth frame and the closed-form
update itself, and change two things:

- cap 10 instead of 25: the belief remembers about one second of frames, so saturation costs less;
- evidence weighting: a forced outlier adds w = w_max · f · min(1, n_through / n_sat) to beta instead of
  1, with f the fraction of the expected-visible surface (in the frustum, within range, not occluded)
  that had free space seen through it, n_through those surface voxels, w_max = 3, n_sat = 30; and
  only if f ≥ 0.5. A box standing in plain view is hit where the map has it (f ≈ 0), so it never
  receives a forced outlier whatever the weight; a box that is gone has f ≈ 1.

From saturation a fully seen-through place then removes the object after 5 frames (cap 10, w = 3),
a box seen once after 3 (the "more than two updates" rule). Measured on rendered frames with depth
noise (bench/mapping_rate.py, both cameras at 10 Hz): boxes seen 1 s and 10 s are removed 3 ticks
(6 frames) after their places come into clear view, against 14 and 18 ticks with POCD's cap 25 and
unit forced outlier; 0 false removals over 60 s of still boxes swept in and out of the image, nor
over 150 ticks of 10–200 boxes; the voxel baseline still held 1583 phantom voxels when they went
and 96 after 60 ticks. With the hand camera alone, removal took 5–6 frames (tests).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from core.mapping import association, consistency
from core.mapping.local_edf import EDFGrid, local_edf, mark_boxes
from core.mapping.registration import align
from core.mapping.scene_points import ScenePoints, latest_time
from core.mapping.segmentation import Segment, segment, voxelise
from core.mapping.tracked_object import TrackedObject
from core.mapping.visibility import THROUGH, FrameView, VisibilityCounts, count
from core.mapping.world_map import TIMING_KEYS
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import DepthFrame, LocalEDF, ObjectMapSnapshot, ObjectStatus, Observation, Posterior

log = logging.getLogger(__name__)

@dataclass
class Observed:
    """What one frame saw of a matched object: points (N×3, world), an even sample of them and the
    sample's distances to the object (truncated at the association cap; the cost, the registration
    trigger and Delta all use them, so they are computed once)."""

    obj: TrackedObject
    points: np.ndarray
    sample: np.ndarray
    distances: np.ndarray


EDF_PAD_M = 0.5
"""The EDT runs on the window grown by this, so objects just outside still shape the field near its edge."""


class ObjectMapper:
    """POCD object-level map behind the `WorldMap` interface."""

    def __init__(self, robot: RobotModel, params: MappingParams | None = None) -> None:
        self.robot = robot
        self.params = params or MappingParams()
        self.scene_points = ScenePoints(robot, self.params)
        self.objects: dict[int, TrackedObject] = {}
        self.removed_ids: list[int] = []
        self.timings_ms: dict[str, float] = dict.fromkeys(TIMING_KEYS, 0.0)
        self.frames_integrated = 0
        self.last_matched = 0
        """Distinct objects observed (matched) by the last `integrate`."""
        self._next_id = 1
        self._t = 0.0

    # --- WorldMap ---------------------------------------------------------------------------------

    def integrate(self, obs: Observation) -> None:
        """Fuse every frame of `obs` (one POCD update per object and frame)."""
        timings = dict.fromkeys(TIMING_KEYS, 0.0)
        timings["edf"] = self.timings_ms.get("edf", 0.0)
        seen: set[int] = set()
        for frame, points in self.scene_points.each(obs, timings):
            seen |= self._integrate_frame(frame, points, timings)
        self.last_matched = len(seen)
        self._t = latest_time(self._t, obs)
        self.timings_ms = timings

    def snapshot(self) -> ObjectMapSnapshot:
        objects = tuple(o.snapshot() for o in self.objects.values())
        return ObjectMapSnapshot(t=self._t, objects=objects, removed_ids=tuple(self.removed_ids))

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        """Signed EDF (9a–9b) of the live objects' boxes in the window around `centre_xy`."""
        t0 = time.perf_counter()
        p = self.params
        grid = EDFGrid.around(np.asarray(centre_xy, dtype=float), p.edf_window_m, p.edf_voxel_m, EDF_PAD_M)
        occupied = grid.empty()
        mark_boxes(grid, occupied, ((o.pose, o.extent) for o in self.objects.values()))
        edf = local_edf(grid, occupied, p.theta_cutoff_m)
        self.timings_ms["edf"] = (time.perf_counter() - t0) * 1e3
        return edf

    def occupied_points(self) -> np.ndarray:
        """Surface voxel centroids (P×3) of the live objects."""
        pts = [o.world_points for o in self.objects.values()]
        return np.concatenate(pts) if pts else np.zeros((0, 3))

    # --- one frame --------------------------------------------------------------------------------

    def _integrate_frame(self, frame: DepthFrame, points: np.ndarray, timings: dict[str, float]) -> set[int]:
        """One frame through the pipeline; returns the ids of the objects it observed."""
        p = self.params
        with _timed(timings, "segmentation"):
            segments = segment(voxelise(points, p.voxel_m), p.min_segment_voxels)
        live = list(self.objects.values())
        with _timed(timings, "association"):
            matches, leftovers = self._associate(segments, live)
        with _timed(timings, "registration"):
            for seen in matches:
                self._register(seen)
        with _timed(timings, "consistency"):
            view = FrameView.of(frame, p.visibility_margin_m, p.depth_noise_coeff_m, p.range_m, p.through_patch_px)
            matched = {seen.obj.id for seen in matches}
            for seen in matches:
                self._update_matched(seen, view)
            for obj in live:
                if obj.id not in matched:
                    self._update_unmatched(obj, view)
            self._remove_changed()
            self._create_all(leftovers)
        self.frames_integrated += 1
        return matched

    # --- association and registration ------------------------------------------------------------

    def _associate(self, segments: list[Segment], live: list[TrackedObject]) -> tuple[list[Observed], list[Segment]]:
        """Matched objects with what was observed of them, and the segments left for new objects."""
        p = self.params
        distances: dict[tuple[int, int], np.ndarray] = {}
        samples = [seg.sample(p.cost_sample_points) for seg in segments]

        def cost(j: int, i: int) -> float:
            distances[j, i] = live[i].distance(samples[j], p.association_cap_m)
            return association.truncated_mean_distance(distances[j, i], p.association_cap_m)

        seg_bounds = np.array([[s.lower, s.upper] for s in segments]).reshape(-1, 2, 3)
        obj_bounds = np.array([o.bounds() for o in live]).reshape(-1, 2, 3)
        candidates = association.overlaps(seg_bounds[:, 0], seg_bounds[:, 1], obj_bounds[:, 0], obj_bounds[:, 1],
                                          p.association_gate_m)
        C = association.cost_matrix(candidates, cost)
        result = association.assign(C, p.association_gate_m)
        parts: dict[int, list[int]] = {i: [j] for j, i in result.pairs}
        merges = association.best_objects(C, result.unmatched_segments, p.merge_gate_m)
        for j, i in merges.items():
            parts.setdefault(i, []).append(j)
        observed = [Observed(live[i], np.concatenate([segments[j].points for j in js]),
                             np.concatenate([samples[j] for j in js]),
                             np.concatenate([distances[j, i] for j in js])) for i, js in parts.items()]
        leftovers = [segments[j] for j in result.unmatched_segments if j not in merges]
        return observed, leftovers

    def _register(self, seen: Observed) -> None:
        """Move the object when its observation sits off its surface and ICP explains that by a motion."""
        p = self.params
        if np.mean(seen.distances > p.registration_trigger_m) < 0.2:
            return
        obj = seen.obj
        result = align(seen.sample, obj.world_points, p.icp_max_correspondence_m, p.icp_max_iterations,
                       normal_radius_m=2.5 * p.voxel_m)
        moved = seen.sample @ result.T[:3, :3].T + result.T[:3, 3]
        after_d = obj.distance(moved, p.association_cap_m)
        before = association.truncated_mean_distance(seen.distances, p.association_cap_m)
        after = association.truncated_mean_distance(after_d, p.association_cap_m)
        if after < 0.7 * before and before - after > 0.5 * p.voxel_m:
            obj.move(np.linalg.inv(result.T))
            seen.distances = obj.distance(seen.sample, p.association_cap_m)
            log.debug("object %d moved by %s (cost %.3f → %.3f m)", obj.id, np.round(-result.T[:3, 3], 3),
                      before, after)

    # --- consistency ------------------------------------------------------------------------------

    def _update_matched(self, seen: Observed, view: FrameView) -> None:
        """POCD update by Delta, then fuse the points and carve what was seen through."""
        p = self.params
        obj = seen.obj
        within = obj.inside_box(seen.sample, p.tau_m)
        if np.any(within):
            delta = float(np.mean(seen.distances[within]))
            post = consistency.update(obj.posterior, delta, p.semantic_static_s, p.semantic_weight_k, p.tau_m,
                                      p.delta_max_m)
            obj.posterior = consistency.cap(post, p.beta_cap)
            obj.updates += 1
        obj.observations += 1
        carve_check = obj.observations % p.carve_check_every == 0
        if carve_check:
            obj.submap.mark_seen_through(view.classify(obj.world_points) == THROUGH)
        obj.integrate(seen.points)
        if carve_check:
            obj.carve(p.carve_after_misses)

    def _update_unmatched(self, obj: TrackedObject, view: FrameView) -> None:
        """Forced outlier, weighted by the clear view of its place, if it should have been seen."""
        centre, radius = obj.bounding_sphere()
        if not view.may_see(centre, radius):
            return
        counts = count(view.classify(obj.world_points))
        weight = self.forced_outlier_weight(counts)
        if weight > 0.0:
            p = self.params
            post = consistency.forced_outlier(obj.posterior, p.semantic_static_s, p.semantic_weight_k, weight)
            obj.posterior = consistency.cap(post, p.beta_cap)
            obj.updates += 1

    def forced_outlier_weight(self, counts: VisibilityCounts) -> float:
        """w = w_max · f · min(1, n_through / n_sat) if f ≥ f_min and enough surface was expected, else 0."""
        p = self.params
        if counts.expected < p.min_expected_voxels or counts.through_fraction < p.clear_view_fraction:
            return 0.0
        if not p.weight_by_clear_view:
            return p.forced_outlier_weight
        return p.forced_outlier_weight * counts.through_fraction * min(1.0, counts.through / p.clear_view_voxels)

    def _remove_changed(self) -> None:
        p = self.params
        for obj in list(self.objects.values()):
            gone = len(obj.submap) == 0
            changed = obj.posterior.consistency < p.theta_stat and obj.updates > p.min_observations
            if gone or changed:
                obj.status = ObjectStatus.REMOVED
                del self.objects[obj.id]
                self.removed_ids.append(obj.id)
                log.info("object %d removed (E[v] = %.2f after %d updates)", obj.id, obj.posterior.consistency,
                         obj.updates)

    def _create_all(self, leftovers: list[Segment]) -> None:
        """New objects from the leftover segments, largest first; a segment lying on the box of an object
        created just before (the part of one box that an occluder split off) joins it instead."""
        p = self.params
        fresh: list[TrackedObject] = []
        for seg in leftovers:
            sample = seg.sample(p.cost_sample_points)
            costs = [association.truncated_mean_distance(o.distance(sample, p.association_cap_m),
                                                         p.association_cap_m) for o in fresh]
            if costs and min(costs) < p.merge_gate_m:
                fresh[int(np.argmin(costs))].integrate(seg.points)
            else:
                fresh.append(self._create(seg.points))

    def _create(self, points: np.ndarray) -> TrackedObject:
        p = self.params
        prior = Posterior(mu=p.mu0_m, sigma=p.sigma0_m, alpha=p.alpha0, beta=p.beta0)
        obj = TrackedObject(self._next_id, points, p.voxel_m, prior, floor_snap_m=p.floor_snap_m)
        self.objects[obj.id] = obj
        self._next_id += 1
        return obj


@contextmanager
def _timed(timings: dict[str, float], key: str) -> Iterator[None]:
    t0 = time.perf_counter()
    yield
    timings[key] += (time.perf_counter() - t0) * 1e3
