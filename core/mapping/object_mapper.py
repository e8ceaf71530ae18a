"""The object-level map (POCD, docs/method.md "Perception", eqs. 1–4): depth frames in, objects out.

Per depth frame:

1. points: unproject (every `pixel_stride`-th pixel, range cut-off), drop the floor and the robot
   (`scene_points.py`);
2. segmentation: 5 cm voxels, 26-connected clusters of at least `min_segment_voxels` (`segmentation.py`);
3. association: cost = truncated mean distance of a segment's (sampled) voxels to an object, i.e. to
   its submap surface M_i or, for a box-like object, its fitted box's faces, whichever is nearer;
   Hungarian with a gate. The voxels of a segment go to the objects whose surfaces explain them,
   nearest first (touching objects seen as one segment, one object split by an occluder), the
   unexplained rest to the segment's match or else to the object explaining most of the segment (a
   wall continuing beyond its known part); a segment nobody matches or explains is a new object; an
   object that repeats part of a larger one's surface is merged into it (`association.py`);
4. registration: when a fifth of a matched segment lies off a box-like object of pushable size,
   point-to-plane ICP moves the object (a box pushed 20–50 cm keeps its id at its new pose; farther
   moves are a new object and the old one goes by step 5) (`registration.py`); walls are never
   registered (ICP slides a wall along itself onto its newly seen continuation);
5. consistency: a matched object is updated by Delta = mean M_i at the observed points within the
   object grown by tau (its box, or its footprint's columns if it is not box-like, `footprint.py`:
   new surface revealed elsewhere is no change), its submap grows, and every third
   observation by each camera its voxels seen through are counted, those seen through three times running carved
   (and free space seen inside its box makes a box-like object hollow, i.e. mapped by its surface);
   an unmatched object whose expected-visible surface was seen through is a forced outlier
   (`visibility.py`, `consistency.py`); unseen or occluded objects keep their belief; an object with
   E[v] < theta_stat after more than `min_observations` updates is removed;
6. new objects: unmatched segments, with the prior (alpha0, beta0, mu0, sigma0), largest first; a
   segment lying on an object created in the same frame joins it.

Update rate, cap and evidence weighting (our choice next to POCD's)
-------------------------------------------------------------------
POCD updates once per frame, caps alpha and beta at 25 and counts a forced outlier as one outlier.
From a saturated belief (a box seen for a few seconds) that takes about 35 frames of a clear view of
the empty place to fall under 0.4 (`tests/core/mapping/test_map_consistency.py` reproduces 3, 6 and 35
for boxes seen 1, 3 and 30 times). We keep one update per depth frame and the closed-form
update itself, and change two things:

- cap 10 instead of 25: the belief remembers about one second of frames, so saturation costs less;
- evidence weighting: a forced outlier adds w = w_max · f_r · min(1, n_through / n_sat) to beta instead of
  1, with n_through the surface voxels that had free space seen through them and f_r their fraction of
  the expected-visible surface voxels (in the frustum, within range, not occluded) whose pixels returned
  depth, w_max = 3, n_sat = 30; and only if n_through is at least half (f ≥ 0.5) of all expected-visible
  surface voxels, those whose pixels returned nothing included (`visibility.py`: no return is no
  evidence). A box standing in plain view is hit where the map has it (f ≈ 0), so it never receives a
  forced outlier whatever the weight; a box that is gone has f_r ≈ 1 and f ≈ 1 where something returns
  behind its place; a dark box in plain view, whose pixels return nothing, has f ≈ 0 (only a rim).

From saturation a fully seen-through place then removes the object after 5 frames (cap 10, w = 3),
a box seen once after 3 (the "more than two updates" rule). On rendered frames that makes moved boxes
go several times sooner than with POCD's cap and unit weight, with no false removals of still, swept,
dark or many boxes (bench/mapping_rate.py; the figures and conditions are in docs/decisions.md,
"Removal speed").

The local EDF (`local_edf`, 9a–9b, signed) is built from every live object: a box-like object is its
solid box (the fitted box completed where it was not seen: behind a face seen from one side, below it
down to the floor, above it if never seen from above, each cut short by free space seen there;
`completion.py`), any other (rows of boxes joined at corners) its well-supported surface voxels with
the columns under them: close to the ground truth at the robot's collision spheres and seldom
optimistic (docs/decisions.md, "Solid, completed boxes in the EDF").
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

import numpy as np

from core.mapping import association, consistency
from core.mapping.completion import Completion
from core.mapping.frame_association import FrameAssociation, Observed
from core.mapping.local_edf import EDFGrid, box_field, column_field, local_edf, mark_points, window_axes
from core.mapping.registration import align
from core.mapping.scene_points import ScenePoints, latest_time
from core.mapping.segmentation import Segment, segment, voxelise
from core.mapping.tracked_object import TrackedObject
from core.mapping.visibility import HIT, THROUGH, FrameView, VisibilityCounts, count
from core.mapping.world_map import TIMING_KEYS
from core.params import MappingParams
from core.robot.model import RobotModel
from core.types import DepthFrame, LocalEDF, ObjectMapSnapshot, ObjectStatus, Observation

log = logging.getLogger(__name__)

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
        """Ids of the objects taken out of the map: changed (POCD) or merged into another object."""
        self.merged_ids: list[int] = []
        """The part of `removed_ids` merged into another object (a duplicate of part of its surface)."""
        self.merged_into: dict[int, int] = {}
        """Merged id → the object it was merged into (which may have been merged or removed since)."""
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
        timings["edf_columns"] = self.timings_ms.get("edf_columns", 0.0)
        seen: set[int] = set()
        for frame, points in self.scene_points.each(obs, timings):
            seen |= self._integrate_frame(frame, points, timings)
        self.last_matched = len(seen)
        self._t = latest_time(self._t, obs)
        self.timings_ms = timings

    def snapshot(self) -> ObjectMapSnapshot:
        objects = tuple(o.snapshot() for o in self.objects.values())
        return ObjectMapSnapshot(t=self._t, objects=objects, removed_ids=tuple(self.removed_ids),
                                 merged_into=self._merges_into_live())

    def _merges_into_live(self) -> dict[int, int]:
        """Each merged id → the live object its surface ended up in, following later merges (none whose object has
        been removed since)."""
        out = {}
        for gone, keep in self.merged_into.items():
            seen = {gone}
            while keep in self.merged_into and keep not in seen:
                seen.add(keep)
                keep = self.merged_into[keep]
            if keep in self.objects:
                out[gone] = keep
        return out

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        """Signed EDF (9a–9b) in the window around `centre_xy`: box-like objects are their solid boxes
        (`completion.py`), the others their surface voxels with the columns below them (`footprint.py`);
        with `edf_geometry` 'surface', every object is its observed surface voxels (the paper's 9a)."""
        t0 = time.perf_counter()
        p = self.params
        grid = EDFGrid.around(np.asarray(centre_xy, dtype=float), p.edf_window_m, p.edf_voxel_m, EDF_PAD_M)
        if p.edf_geometry == "surface":
            occupied = grid.empty()
            mark_points(grid, occupied, self.occupied_points())
            edf = local_edf(grid, occupied, p.theta_cutoff_m)
        else:
            edf = self._completed_edf(grid)
        self.timings_ms["edf"] = (time.perf_counter() - t0) * 1e3
        return edf

    def _completed_edf(self, grid: EDFGrid) -> LocalEDF:
        """Distances at the nodes to the surfaces themselves: to the solid boxes of box-like objects
        (analytic), to the surface columns of the others (`column_field`, whose ms are `timings_ms["edf_columns"]`:
        the costliest part of the EDF on big surface objects)."""
        p = self.params
        self.timings_ms["edf_columns"] = 0.0
        axes = window_axes(grid)
        boxes = [o for o in self.objects.values() if o.box_like]
        values = box_field(axes, ((o.solid_pose, o.solid.extent) for o in boxes), p.theta_cutoff_m)
        others = [o for o in self.objects.values() if not o.box_like]
        if others:
            points = np.concatenate([o.solid_world_points() for o in others])
            weights = np.concatenate([o.solid_weights() for o in others])
            t0 = time.perf_counter()
            columns = column_field(grid, points, p.theta_cutoff_m, weights, p.surface_shell_ratio)
            self.timings_ms["edf_columns"] = (time.perf_counter() - t0) * 1e3
            values = np.minimum(values, columns)
        return LocalEDF(origin=grid.window_origin, voxel=grid.voxel, values=np.ascontiguousarray(values),
                        cutoff=p.theta_cutoff_m)

    def occupied_points(self) -> np.ndarray:
        """Well-supported surface voxel centroids (P×3) of the live objects (no single-return noise specks)."""
        pts = [o.solid_world_points() for o in self.objects.values()]
        return np.concatenate(pts) if pts else np.zeros((0, 3))

    # --- one frame --------------------------------------------------------------------------------

    def _integrate_frame(self, frame: DepthFrame, points: np.ndarray, timings: dict[str, float]) -> set[int]:
        """One frame through the pipeline; returns the ids of the objects it observed."""
        p = self.params
        with _timed(timings, "segmentation"):
            segments = segment(voxelise(points, p.voxel_m), p.min_segment_voxels)
        live = list(self.objects.values())
        with _timed(timings, "association"):
            found = self._associate(segments, live)
            matches = found.observed(p.cost_sample_points, p.association_cap_m)
            self._forget(found.gone(), "merged into another object")
            self.merged_ids.extend(found.gone())
            self.merged_into.update({gone: keep.id for gone, keep in found.keepers().items()})
            live = [o for o in live if o.id in self.objects]
        with _timed(timings, "registration"):
            for seen in matches:
                self._register(seen)
        with _timed(timings, "consistency"):
            view = FrameView.of(frame, p)
            matched = {seen.obj.id for seen in matches}
            for seen in matches:
                self._update_matched(seen, view, frame.camera)
            for obj in live:
                if obj.id not in matched:
                    self._update_unmatched(obj, view)
            self._remove_changed()
            self._create_all(found.leftovers, view.camera_position)
        for obj in self.objects.values():
            if np.isnan(obj.last_seen_t):  # created by this frame
                obj.first_seen_t, obj.first_camera = frame.t, frame.camera
            if obj.id in matched or np.isnan(obj.last_seen_t):  # matched now, or created by this frame
                obj.last_seen_t = frame.t
        self.frames_integrated += 1
        return matched

    # --- association and registration ------------------------------------------------------------

    def _associate(self, segments: list[Segment], live: list[TrackedObject]) -> FrameAssociation:
        """Who saw what: the points of each segment go to the objects whose surface explains them
        (nearest first), what no surface explains to the segment's Hungarian match or else to the object
        explaining most of the segment (it continues that surface); segments nobody explains or matches
        are new objects; objects found to repeat part of another's surface are merged into it."""
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
        owner = dict(association.assign(C, p.association_gate_m).pairs)
        out = FrameAssociation()
        for j, seg in enumerate(segments):
            explainers = [i for i in map(int, np.nonzero(candidates[j])[0])
                          if association.explained_fraction(distances[j, i], p.explain_m) >= p.split_fraction]
            primary = owner.get(j)
            if not [i for i in explainers if i != primary]:
                if primary is None:
                    out.leftovers.append(seg)  # no explainers either
                else:
                    out.add(live[primary], seg.points, samples[j], distances[j, primary])
                continue
            self._split(seg, [live[i] for i in explainers], None if primary is None else live[primary], out)
        out.merge()
        return out

    def _split(self, seg: Segment, explainers: list[TrackedObject], primary: TrackedObject | None,
               out: FrameAssociation) -> None:
        """Share one segment among the objects whose surfaces explain parts of it (touching objects)."""
        p = self.params
        dist = np.stack([o.distance(seg.points, p.association_cap_m) for o in explainers], axis=1)
        who = association.nearest_owner(dist, p.explain_m)
        out.merges.extend(self._duplicates(dist, explainers))
        for k, obj in enumerate(explainers):
            if np.any(who == k):
                out.add(obj, seg.points[who == k])
        rest = who < 0
        if np.any(rest):
            owner = primary if primary is not None else explainers[int(np.argmax(np.sum(dist < p.explain_m, axis=0)))]
            out.add(owner, seg.points[rest])

    def _duplicates(self, dist: np.ndarray, objects: list[TrackedObject]) -> list[tuple[TrackedObject, TrackedObject]]:
        """(keep, gone) pairs among objects explaining one segment: the smaller (on a tie the newer) goes
        when it repeats part of the larger one's surface, i.e. most of the segment points it explains are
        explained by the other as well, and so is most of its own surface (a box pushed against another is
        not a duplicate: its old surface lies elsewhere, and is carved away as it is seen through)."""
        p = self.params
        near = dist < p.explain_m
        pairs = []
        for a in range(len(objects)):
            for b in range(a + 1, len(objects)):
                small, big = sorted((a, b), key=lambda i: (len(objects[i].submap), -objects[i].id))
                n_small = int(near[:, small].sum())
                if not n_small or np.sum(near[:, small] & near[:, big]) < p.duplicate_fraction * n_small:
                    continue
                surface = objects[small].world_points
                if np.mean(objects[big].distance(surface, p.association_cap_m) < p.explain_m) >= p.duplicate_fraction:
                    pairs.append((objects[big], objects[small]))
        return pairs

    def _register(self, seen: Observed) -> None:
        """Move the object when its observation sits off its surface and ICP explains that by a motion."""
        p = self.params
        obj = seen.obj
        off_surface = np.mean(seen.distances > p.registration_trigger_m)
        if off_surface < p.registration_trigger_fraction or not self._movable(obj):
            return
        result = align(seen.sample, obj.world_points, p.icp_max_correspondence_m, p.icp_max_iterations,
                       p.icp_normal_neighbours)
        moved = seen.sample @ result.T[:3, :3].T + result.T[:3, 3]
        after_d = obj.distance(moved, p.association_cap_m)
        before = association.truncated_mean_distance(seen.distances, p.association_cap_m)
        after = association.truncated_mean_distance(after_d, p.association_cap_m)
        gain_m = p.registration_min_gain_voxels * p.voxel_m
        explained = np.mean(after_d > p.registration_trigger_m) < p.registration_trigger_fraction
        if explained and after < p.registration_accept_ratio * before and before - after > gain_m:
            obj.move(np.linalg.inv(result.T))
            seen.distances = obj.distance(seen.sample, p.association_cap_m)
            log.debug("object #%d moved by %s (cost %.3f → %.3f m)", obj.id, np.round(-result.T[:3, 3], 3),
                      before, after)

    def _movable(self, obj: TrackedObject) -> bool:
        """Only box-like objects of a pushable size are registered: ICP on a wall slides it along itself
        to cover the wall's newly seen continuation."""
        return obj.box_like and float(np.max(obj.extent[:2])) <= self.params.registration_max_extent_m

    # --- consistency ------------------------------------------------------------------------------

    def _update_matched(self, seen: Observed, view: FrameView, camera: str) -> None:
        """POCD update by Delta, then fuse the points and carve what was seen through (checked every
        `carve_check_every` observations by each camera)."""
        p = self.params
        obj = seen.obj
        within = obj.covers(seen.sample, p.tau_m)
        if np.any(within):
            delta = float(np.mean(seen.distances[within]))
            post = consistency.update(obj.posterior, delta, p.semantic_static_s, p.semantic_weight_k, p.tau_m,
                                      p.delta_max_m)
            obj.posterior = consistency.cap(post, p.beta_cap)
            obj.updates += 1
        carve_check = obj.observed_by(camera) % p.carve_check_every == 0
        obj.saw_from(view.camera_position)
        if carve_check:
            obj.submap.mark_seen_through(view.classify(obj.world_points) == THROUGH)
            self._check_hollow(obj, view)
            self._check_completion(obj, view)
        obj.integrate(seen.points, view.camera_position)
        if carve_check:
            obj.carve(p.carve_after_misses)

    def _check_hollow(self, obj: TrackedObject, view: FrameView) -> None:
        """Free space seen inside a box-like object's box (an L of walls whose box spans the corridor
        between them) makes it hollow: from then on it is its surface, not its box."""
        p = self.params
        if not obj.box_like:
            return
        inside = obj.interior(p.edf_voxel_m, p.explain_m)
        if np.sum(view.classify(inside) == THROUGH) >= p.hollow_min_through:
            obj.hollow = True
            log.info("object #%d: free space seen inside its box %s, mapped by its surface", obj.id,
                     np.round(obj.extent, 2))

    def _check_completion(self, obj: TrackedObject, view: FrameView) -> None:
        """Free space seen where a box-like object's unseen parts could be shortens its solid box."""
        if not obj.box_like:
            return
        samples = obj.completion_samples()
        if len(samples):
            labels = view.classify(samples)
            obj.mark_completion(samples, labels == THROUGH, labels == HIT)

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

    def note_change_evidence(self, ids: Iterable[int]) -> None:
        """Localization found these objects off their surfaces after aligning a frame: one forced outlier each
        of the paper's weight 1 (a 0.1 m move sits inside tau, so Delta alone barely lowers E[v])."""
        p = self.params
        for object_id in ids:
            obj = self.objects.get(object_id)
            if obj is not None:
                post = consistency.forced_outlier(obj.posterior, p.semantic_static_s, p.semantic_weight_k, 1.0)
                obj.posterior = consistency.cap(post, p.beta_cap)
                obj.updates += 1
        self._remove_changed()

    def forced_outlier_weight(self, counts: VisibilityCounts) -> float:
        """w = w_max · f_r · min(1, n_through / n_sat) if f ≥ f_min and enough surface was expected, else 0
        (f: the seen-through fraction of the expected-visible surface, f_r: of its part that returned depth)."""
        p = self.params
        if counts.expected < p.min_expected_voxels or counts.through_fraction < p.clear_view_fraction:
            return 0.0
        if not p.weight_by_clear_view:
            return p.forced_outlier_weight
        return p.forced_outlier_weight * counts.through_of_returns * min(1.0, counts.through / p.clear_view_voxels)

    def _remove_changed(self) -> None:
        """Remove the objects with E[v] < theta_stat after more than `min_observations` updates (and any
        whose whole surface was carved away)."""
        p = self.params
        changed = [o.id for o in self.objects.values()
                   if len(o.submap) == 0 or (o.posterior.consistency < p.theta_stat and o.updates > p.min_observations)]
        self._forget(changed, "changed")
        if changed:  # merges into a removed object lead nowhere now (removed objects never come back)
            self.merged_into = self._merges_into_live()

    def _forget(self, ids: Iterable[int], why: str) -> None:
        """Take objects out of the map; their ids are published as removed."""
        for object_id in ids:
            obj = self.objects.pop(object_id)
            obj.status = ObjectStatus.REMOVED
            self.removed_ids.append(object_id)
            log.info("object #%d removed, %s (E[v] = %.2f after %d updates)", object_id, why,
                     obj.posterior.consistency, obj.updates)

    def _create_all(self, leftovers: list[Segment], camera: np.ndarray) -> None:
        """New objects from the leftover segments, largest first; a segment lying on the box of an object
        created just before (the part of one box that an occluder split off) joins it instead."""
        p = self.params
        fresh: list[TrackedObject] = []
        for seg in leftovers:
            sample = seg.sample(p.cost_sample_points)
            costs = [association.truncated_mean_distance(o.distance(sample, p.association_cap_m),
                                                         p.association_cap_m) for o in fresh]
            if costs and min(costs) < p.merge_gate_m:
                fresh[int(np.argmin(costs))].integrate(seg.points, camera)
            else:
                fresh.append(self._create(seg.points, camera))

    def _create(self, points: np.ndarray, camera: np.ndarray | None = None) -> TrackedObject:
        p = self.params
        prior = p.prior()
        obj = TrackedObject(self._next_id, points, p.voxel_m, prior, floor_snap_m=p.floor_snap_m,
                            box_fill_max_m=p.box_fill_max_m,
                            completion=Completion(p.edf_voxel_m, p.assumed_depth_m, p.carve_after_misses),
                            camera_world=camera)
        self.objects[obj.id] = obj
        self._next_id += 1
        return obj


@contextmanager
def _timed(timings: dict[str, float], key: str) -> Iterator[None]:
    t0 = time.perf_counter()
    yield
    timings[key] += (time.perf_counter() - t0) * 1e3
