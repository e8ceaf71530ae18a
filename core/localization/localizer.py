"""`Localizer`: the base pose estimate, T_world←odom, from odometry and gated registrations of depth frames
against the map's trusted surfaces (docs/method.md, "State estimation").

One registration (`correct`): the frame (posed in the world by the current estimate, at its exposure) is
thinned and aligned by GICP to the floor and the trusted surfaces near the base, within a radius tied to
the current uncertainty. Objects whose points sit off their reference surface after alignment leave the
reference (the alignment runs again without them) and are handed to the map as change evidence. The result
passes the gates (`gates.py`), its unconstrained directions are masked (`degeneracy.py`), and the EKF update
(`pose_filter.py`) becomes due at the frame's stamp plus the modelled processing time (`apply_due`), so
lockstep runs stay deterministic. Until enough trusted surface is in view, odometry alone is in charge.

Loop closure (`loop_closure.py`, `LocalizationParams.loop_closure`): the registered frames are kept as keyframes of a
pose graph; where an earlier visit's keyframe is in reach, the frame registers against those keyframes (placed by the
optimised graph) instead of the map's surfaces, and an accepted closure re-optimises the graph, T_world←odom then
following the frame's optimised node.

Thread use: `correct` is the slow part and touches only the filter's covariance and the pending queue under
`lock`; `predict`, `apply_due` and `world_pose` are cheap (a control thread may call them; issue 28 runs
`correct` on a thread of its own in live mode).
"""

from __future__ import annotations

import math
import threading
from collections import Counter, deque
from collections.abc import Iterable
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np

from core.angles import wrap_angle
from core.localization import degeneracy, gates, health, lost, registration, scan, se2, see_through
from core.localization.correction import Correction
from core.localization.frozen_surfaces import FrozenSurfaces
from core.localization.gates import Verdict
from core.localization.health import LocalizationHealth
from core.localization.loop_closure import LoopClosure
from core.localization.measurement import Measurement, measure
from core.localization.pose_filter import PoseFilter, Update, position_std
from core.localization.reference import FLOOR_ID, Reference, build
from core.params import LocalizationParams
from core.types import DepthFrame, LocalizationStatus, PoseEstimate, ReferenceSurface

DEGENERATE = "degenerate"
"""`Localizer.counts` key: accepted corrections with at least one direction masked."""
OUTCOMES = {Verdict.ACCEPTED: "accepted", Verdict.DEGENERATE: "degenerate",
            **dict.fromkeys(lost.UNJUDGED, "no_reference")}
"""`Localizer.tally` key of a verdict; every other verdict is a gate's refusal, "rejected". A frame with too few
points has nothing to register, like one without trusted surface in view: no gate refused the pose."""
QUIET = (*lost.UNJUDGED, Verdict.DEGENERATE)
"""Verdicts that neither confirm nor doubt the pose: at rest after one of these, the untrusted clock stands still."""
QUIET_FRESH_S = 1.0
"""A quiet verdict stops the untrusted clock only while it is this recent (s of robot time): frames still come."""
REST_MPS = 0.01
REST_RADPS = 0.01
"""Odometry slower than these (m/s, rad/s) is at rest: its drift, a walk per metre and radian, does not grow."""


class ObjectVerdict(NamedTuple):
    """The objects a registration found off their surfaces (`off`), how many it judged, whether something vouched for
    the prediction, and the camera pose (4x4) they were judged at."""

    off: tuple[int, ...]
    judged: int
    vouched: bool
    T_world_camera: np.ndarray


class Localizer:
    """Odometry prediction, gated scan-to-map corrections, and the estimate T_world←odom."""

    def __init__(self, params: LocalizationParams | None = None, start_t: float = 0.0) -> None:
        """`start_t`: robot time (s) the start pose (the world frame) was known at; the age of the first correction
        counts from it."""
        self.params = p = params or LocalizationParams()
        self.start_t = start_t
        self.filter = PoseFilter(p.initial_sigma_m, p.initial_sigma_rad)
        self.lock = threading.Lock()
        self.counts: Counter[str] = Counter()
        self.corrections: deque[Correction] = deque(maxlen=100_000)
        self.status = LocalizationStatus.ODOMETRY
        self._pending: deque[tuple[float, np.ndarray]] = deque()
        self._odom: np.ndarray | None = None
        self._last_registration_t = -math.inf
        self._excluded: dict[int, float] = {}
        self._agreed: dict[int, float] = {}
        """Object id → the latest frame time it fitted an accepted registration."""
        self._loop_accepted_t = -math.inf
        """Frame time of the latest accepted loop closure (it vouches for the pose for `loop_vouch_s`)."""
        self._evidence: list[int] = []
        self._target: tuple[ReferenceSurface | None, tuple, Reference, registration.Target] | None = None
        self.tally: Counter[str] = Counter()
        """Registrations by outcome for the operator (`health`): accepted, rejected, degenerate, no_reference."""
        self._accepted_t: deque[float] = deque(maxlen=1000)
        """Frame times of recent accepted corrections (the correction rate)."""
        self.frozen = FrozenSurfaces(p.freeze_sigma_m, p.freeze_grow_m) if p.freeze_reference else None
        """The trusted surfaces where they were when first trusted (`frozen_surfaces.py`); None: the map's
        surfaces as they are now."""
        self.lost = lost.LostWatch(p)
        """Refusals in a row, the lost state, the frames' fate and the global search (`lost.py`)."""
        self.loops = LoopClosure(p) if p.loop_closure else None
        """The pose graph of keyframes and its loop closures (`loop_closure.py`); None: the filter alone."""
        self._T_chain = np.zeros(3)
        """T_world←odom with the map registrations' corrections alone (`graph_follows_map`; loop closures and
        re-anchorings left out): the pose graph's nodes are tied by the increments of T_chain ∘ odometry."""
        self._T_log: deque[tuple[float, np.ndarray]] = deque([(-math.inf, np.zeros(3))], maxlen=10_000)
        """(robot time, T_world←odom from then on): the odometry pose of a frame's base from its world pose."""
        self._odom_t: float | None = None
        self._last_verdict: tuple[float, Verdict] | None = None
        """Frame time and verdict of the latest registration."""
        self.rest_s = 0.0
        """Robot time (s) since the last accepted correction that the base stood at rest with the latest
        registration quiet (`QUIET`): not counted toward `untrusted_after_s`."""

    # --- cheap: every tick ----------------------------------------------------------------------------

    @property
    def world_from_odom(self) -> np.ndarray:
        """The estimate (x, y, yaw): world pose = T_world←odom ∘ odometry pose."""
        return self.filter.T_world_odom.copy()

    def predict(self, odom_pose: np.ndarray, t: float | None = None) -> None:
        """Grow the covariance by the odometry's motion since the last call; with robot time t, count the time the
        base stood at rest with nothing refusing its pose (`rest_s`)."""
        odom_pose = np.asarray(odom_pose, float)[:3]
        with self.lock:
            if self._odom is not None:
                p = self.params
                self.filter.predict(self._odom, odom_pose, p.drift_m_per_sqrt_m, p.drift_rad_per_sqrt_rad)
                if t is not None and self._odom_t is not None and t > self._odom_t:
                    self._count_rest(self._odom, odom_pose, t - self._odom_t, t)
            self._odom = odom_pose.copy()
            self._odom_t = t

    def _count_rest(self, odom_from: np.ndarray, odom_to: np.ndarray, dt: float, t: float) -> None:
        """Add dt to `rest_s` if the odometry stood still over it and the latest registration, recent, was quiet:
        standing still, wheel odometry does not drift, and a frame with nothing to register doubts nothing (at a
        table at arm's length the base camera sees too few points, and the pose stays what it was). Refusals, no
        frames at all, and every moving second still count (call under `lock`)."""
        still = (float(np.hypot(*(odom_to[:2] - odom_from[:2]))) <= REST_MPS * dt
                 and abs(wrap_angle(float(odom_to[2] - odom_from[2]))) <= REST_RADPS * dt)
        last = self._last_verdict
        if still and last is not None and last[1] in QUIET and t - last[0] <= QUIET_FRESH_S:
            self.rest_s += dt

    def schedule(self, apply_t: float, delta: np.ndarray) -> None:
        """Queue a correction delta (T_world←odom update) to apply at robot time apply_t (call under `lock`)."""
        self._pending.append((apply_t, delta))

    def apply_due(self, t: float) -> bool:
        """Apply the corrections due by robot time t; whether the estimate changed."""
        changed = False
        with self.lock:
            while self._pending and self._pending[0][0] <= t + 1e-9:
                self.filter.apply(self._pending.popleft()[1])
                changed = True
            if self.lost.resume_t is not None and self.lost.resume_t <= t + 1e-9:  # re-anchored: found again
                self.lost.applied(t, self.lost.resume_delta)
                self.status = LocalizationStatus.LOCALIZED
                if self.loops is not None and np.any(self.lost.resume_delta):
                    self.loops.break_chain()  # re-anchored after a jump: no odometry factor across it
            if changed:
                self._T_log.append((t, self.filter.T_world_odom.copy()))
        return changed

    def estimate(self, t: float, odom_pose: np.ndarray) -> PoseEstimate:
        with self.lock:
            return PoseEstimate(t, self.filter.world_pose(odom_pose), self.filter.P.copy(), self.status)

    def health(self, t: float, delta_safe_m: float) -> LocalizationHealth:
        """The estimate's health at robot time t against the controller's delta_safe (`health.py`)."""
        p = self.params
        with self.lock:
            P = self.filter.P.copy()
            tally = Counter(self.tally)
            times = list(self._accepted_t)
            rest = self.rest_s
        last = times[-1] if times else None
        since = t - (self.start_t if last is None else last)
        sigma = health.position_sigma(P)
        recent = sum(1 for s in times if t - health.RATE_WINDOW_S < s <= t + 1e-9)
        reason = health.untrusted_reason(sigma, since, tally["accepted"], tally["rejected"], tally["degenerate"],
                                         tally["no_reference"], delta_safe_m, p, rest)
        reason = "; ".join(r for r in (self.lost.reason(), reason) if r) or None
        return LocalizationHealth(
            t=t, covariance=P, sigma_xy_m=sigma, sigma_yaw_rad=float(np.sqrt(max(P[2, 2], 0.0))),
            accepted=tally["accepted"], rejected=tally["rejected"], degenerate=tally["degenerate"],
            no_reference=tally["no_reference"], last_accepted_t=last, since_accepted_s=since,
            accepted_per_s=recent / health.RATE_WINDOW_S, untrusted=reason, at_rest_s=rest,
            margin_growth_m=health.margin_growth(sigma, delta_safe_m, p))

    def wants(self, frame: DepthFrame) -> bool:
        """Whether `frame` is one to register (its camera, and due at `rate_hz`)."""
        p = self.params
        return frame.camera == p.camera and frame.t >= self._last_registration_t + 1.0 / p.rate_hz - 1e-9

    def take_change_evidence(self) -> tuple[int, ...]:
        """Objects found disagreeing since the last call (for the map's consistency update)."""
        with self.lock:
            ids, self._evidence = tuple(self._evidence), []
        return ids

    # --- slow: one registration -----------------------------------------------------------------------

    def correct(self, frame: DepthFrame, base_pose: np.ndarray, surface: ReferenceSurface | None) -> Correction:
        """Register `frame` (posed in the world by the current estimate, at its exposure; the base was at
        `base_pose` then) against the floor and `surface`; a correction that passes the gates becomes due
        at frame.t + processing_s."""
        p = self.params
        self._last_registration_t = frame.t
        self._excluded = {i: until for i, until in self._excluded.items() if until > frame.t}
        if self.lost.lost:
            return Correction(frame.t, Verdict.SEARCHED, **lost.search_frame(self, frame, np.asarray(base_pose, float),
                                                                              surface))
        if self.frozen is not None:
            with self.lock:
                sigma = self.filter.sigma_xy_m(p.max_range_m / 2)
            surface = self.frozen.update(surface, sigma, self._excluded)
        thinned = None
        if self.loops is not None:
            anchor = self.loops.anchor(np.asarray(base_pose, float), frame.t)
            if anchor is not None:
                thinned = registration.thin(scan.camera_points(frame, p.stride_px, p.max_range_m), p.source_voxel_m)
                closed = self._close(anchor, frame, np.asarray(base_pose, float), surface, *thinned)
                if closed is not None:
                    return self._record(closed)
        ref, target, ref_ms = self.prepared_reference(surface, np.asarray(base_pose[:2], float))
        trusted = ref.object_ids != FLOOR_ID
        if np.sum(scan.in_view(ref.points[trusted], frame, p.max_range_m)) < p.min_trusted_points:
            return self._record(Correction(frame.t, Verdict.NO_REFERENCE, reference_ms=ref_ms))
        source, n = thinned or registration.thin(scan.camera_points(frame, p.stride_px, p.max_range_m),
                                                 p.source_voxel_m)
        if n < p.min_source_points:
            return self._record(Correction(frame.t, Verdict.TOO_FEW_POINTS, reference_ms=ref_ms))
        with self.lock:
            radius = float(np.clip(p.radius_sigmas * self.filter.sigma_xy_m(p.max_range_m / 2) + p.radius_margin_m,
                                   p.radius_min_m, p.radius_max_m))
        result = registration.register(target, source, frame.T_world_camera, radius, p.max_iterations)
        ms = result.ms
        loop_vouches = frame.t - self._loop_accepted_t <= p.loop_vouch_s + 1e-9
        verdict = self._judge_objects(ref, target, source, frame, result.T_world_camera, radius, loop_vouches)
        disagreeing = verdict.off
        if disagreeing and 2 * len(disagreeing) > verdict.judged and not verdict.vouched:  # the pose is in doubt
            return self._record(Correction(frame.t, Verdict.INCONSISTENT, registration_ms=ms, reference_ms=ref_ms,
                                           off=disagreeing))
        if disagreeing:
            surface, ref, target, source, result, more_ms = self._register_without(
                disagreeing, frame, base_pose, surface, source, radius, (ref, target, verdict.T_world_camera))
            ref_ms += more_ms
            ms += result.ms
        pts = np.asarray(source.points())[:, :3]
        correction = self._judge(frame, np.asarray(base_pose, float), result, pts, ms, ref_ms, disagreeing)
        small_refusal = correction.verdict == Verdict.CHI2 and not correction.jump
        needs_fit = small_refusal or correction.verdict == Verdict.ACCEPTED  # only these read the objects' fit
        fit = self._object_residuals(ref, target, source, result.T_world_camera) if needs_fit else {}
        if small_refusal:
            moved = self._agreed_before(fit, frame.t)
            if moved:  # they fitted the pose a moment ago and now pull it: they moved, the base did not jump
                surface, ref, target, source, result, more_ms = self._register_without(
                    moved, frame, base_pose, surface, source, radius, (ref, target, result.T_world_camera))
                pts = np.asarray(source.points())[:, :3]
                correction = self._judge(frame, np.asarray(base_pose, float), result, pts, ms + result.ms,
                                         ref_ms + more_ms, disagreeing + moved)
                fit = self._object_residuals(ref, target, source, result.T_world_camera)
            elif self._view_agrees(fit):
                self._grow(correction.innovation)
        if correction.verdict == Verdict.ACCEPTED:
            self._agreed.update({i: frame.t for i, d in fit.items() if d <= p.disagreement_m})
        if self.loops is not None:
            pose = correction.pose if correction.pose is not None else np.asarray(base_pose, float)
            with self.lock:
                P = self.filter.P.copy()
            chain = se2.compose(self._T_chain, self._odom_at(frame.t, base_pose))
            self.loops.after_map_registration(frame, np.asarray(base_pose, float), pose, chain, P, pts, ref, target)
        return self._record(correction)

    def _register_without(self, ids: tuple[int, ...], frame: DepthFrame, base_pose: np.ndarray,
                          surface: ReferenceSurface | None, source, radius: float,
                          judged: tuple[Reference, registration.Target, np.ndarray]
                          ) -> tuple[ReferenceSurface | None, Reference, registration.Target, Any,
                                     registration.Result, float]:
        """Leave `ids` out (as change evidence) and register the frame again against what remains, without the
        frame's points that lay on them (`judged`: the reference, target and camera pose they were judged at): those
        points have no partner left, and counted in the inlier share they would refuse the frame for what was left
        out. The surface without them, its reference and target, the source, the new result and the ms spent
        rebuilding the reference."""
        surface = self._leave_out(ids, frame.t, surface)
        ref, target, ref_ms = self.prepared_reference(surface, np.asarray(base_pose[:2], float))
        source = self._source_without(source, ids, *judged)
        result = registration.register(target, source, frame.T_world_camera, radius, self.params.max_iterations)
        return surface, ref, target, source, result, ref_ms

    def _source_without(self, source, ids: tuple[int, ...], ref: Reference, target: registration.Target,
                        T: np.ndarray):
        """The frame's thinned points (camera frame) less those whose nearest reference point, at camera pose T, is
        on one of `ids` (`_assign`)."""
        pts = np.asarray(source.points())[:, :3]
        _, on, _, near = self._assign(ref, target, _placed(pts, T))
        drop = near & np.isin(on, np.asarray(ids, int))
        if not np.any(drop):
            return source
        return registration.thin(pts[~drop], self.params.source_voxel_m)[0]

    def _odom_at(self, t: float, base_pose: np.ndarray) -> np.ndarray:
        """The odometry pose of the base whose world pose at robot time t was `base_pose` (T_world←odom then)."""
        return se2.compose(se2.inverse(self._world_from_odom_at(t)), np.asarray(base_pose, float))

    def _world_from_odom_at(self, t: float) -> np.ndarray:
        for since, T in reversed(self._T_log):
            if since <= t + 1e-9:
                return T
        return self._T_log[0][1]

    def _close(self, anchor: int, frame: DepthFrame, base_pose: np.ndarray, surface: ReferenceSurface | None,
               source, n: int) -> Correction | None:
        """A loop closure (`loop_closure.py`) of the frame (`source`: its `n` thinned points) onto the keyframes an
        earlier visit kept around `anchor`, when it passes its gates: the correction, due at frame.t + processing_s,
        T_world←odom following the optimised graph and P its covariance where that is surer than the filter's. None:
        refused (the map's surfaces are then the reference, registering the same thinned points)."""
        p = self.params
        assert self.loops is not None
        if n < p.min_source_points:
            return None
        # the trusted objects and the ids merged into them (`trusted_surface` offers only those); not less the map
        # registration's exclusions: those were judged at a pose that may have drifted, and the keyframes are what
        # overrules it (objects a loop closure found off have left the keyframes already)
        live: set[int] = set()
        if surface is not None:
            live = set(np.unique(np.asarray(surface.object_ids, int)).tolist()) | set(surface.merged_into)
        with self.lock:
            P = self.filter.P.copy()
        chain = se2.compose(self._T_chain, self._odom_at(frame.t, base_pose))
        closure = self.loops.close(anchor, frame, base_pose, chain, P, source, live, self._disagreeing)
        if closure is None:
            return None
        c = closure.correction
        if c.disagreeing:
            for i in c.disagreeing:
                self._excluded[i] = frame.t + p.exclusion_s
            with self.lock:
                self._evidence.extend(c.disagreeing)
        if c.verdict != Verdict.ACCEPTED:
            self.counts[f"loop_{c.verdict.value}"] += 1
            return None
        self.counts["loop_accepted"] += 1
        if closure.P is None:  # no factor due: the filter alone, against the keyframes
            assert closure.measurement is not None
            m = closure.measurement
            update, apply_t, innovation = self._fuse(frame.t, base_pose, m.pose, m.directions)
            if apply_t is None:
                # the keyframes held against an over-sure filter: P grows by an innovation under a jump's size
                jump = self._is_jump(innovation)
                if not jump:
                    self._grow(innovation)
                return replace(c, verdict=Verdict.CHI2, nis=update.nis, jump=jump, innovation=innovation)
            self._loop_accepted_t = frame.t
            return replace(c, delta=update.delta, nis=update.nis, apply_t=apply_t,
                           pose=se2.compose(update.delta, base_pose))
        with self.lock:
            if position_std(closure.P, p.max_range_m / 2) < self.filter.sigma_xy_m(p.max_range_m / 2):
                self.filter.P = closure.P  # surer after the closure; never less sure: P also grows the margin (health)
            apply_t = self._commit(frame.t, c.delta)
        self._loop_accepted_t = frame.t
        return replace(c, apply_t=apply_t)

    def _fuse(self, t: float, base_pose: np.ndarray, measured: np.ndarray, dirs: degeneracy.Directions
              ) -> tuple[Update, float | None, np.ndarray]:
        """The filter updated along `dirs` by the `measured` base pose and its correction scheduled (`_commit`);
        when the χ² gate refuses it, nothing changes. The update, its apply time (None: refused) and the
        innovation (x, y, yaw) in the constrained directions."""
        p = self.params
        with self.lock:
            update = self.filter.update(base_pose, measured, dirs, p.sigma_xy_m, p.sigma_yaw_rad,
                                        5.0 * p.degenerate_information)
            innovation = _constrained_innovation(measured, base_pose, dirs)
            if not gates.chi2_passes(update.nis, update.dof, p):
                return update, None, innovation
            self.filter.P = update.P
            return update, self._commit(t, update.delta), innovation

    def _commit(self, t: float, delta: np.ndarray) -> float:
        """A correction of a frame at robot time `t` scheduled `processing_s` later, the estimate localized
        from then; its apply time (call under `lock`)."""
        apply_t = t + self.params.processing_s
        self.schedule(apply_t, delta)
        self.status = LocalizationStatus.LOCALIZED
        return apply_t

    def _agreed_before(self, fit: dict[int, float], t: float) -> tuple[int, ...]:
        """The objects that fit a χ²-refused pose and fitted an accepted one within `agreed_recently_s`: the pose
        cannot have moved that far since (the refusal is under a jump), so they did."""
        p = self.params
        return tuple(i for i, d in fit.items()
                     if d <= p.disagreement_m and t - self._agreed.get(i, -math.inf) <= p.agreed_recently_s)

    def _leave_out(self, ids: tuple[int, ...], t: float, surface: ReferenceSurface | None
                   ) -> ReferenceSurface | None:
        """Set objects aside as change evidence for the map; the surface to register against without them."""
        self.set_aside(ids, t)
        if self.frozen is not None and self.params.refreeze_disagreeing:
            self.frozen.forget(ids)
            surface = self.frozen.surface
        with self.lock:
            self._evidence.extend(ids)
        return surface

    def _judge(self, frame: DepthFrame, base_pose: np.ndarray, result: registration.Result, source_points: np.ndarray,
               ms: float, ref_ms: float, disagreeing: tuple[int, ...]) -> Correction:
        p = self.params
        base = Correction(frame.t, Verdict.ACCEPTED, registration_ms=ms, reference_ms=ref_ms, disagreeing=disagreeing,
                          inlier_share=result.inliers / max(result.source_points, 1))
        m = measure(result, frame, base_pose, source_points, p)
        if not isinstance(m, Measurement):
            return replace(base, verdict=m)
        measured, dirs = m.pose, m.directions
        update, apply_t, innovation = self._fuse(frame.t, base_pose, measured, dirs)
        if apply_t is None:
            return replace(base, verdict=Verdict.CHI2, dof=update.dof, nis=update.nis,
                           jump=self._is_jump(innovation), innovation=innovation)
        if p.graph_follows_map:
            with self.lock:
                self._T_chain = se2.compose(update.delta, self._T_chain)
        if dirs.degenerate:
            self.counts[DEGENERATE] += 1
        return replace(base, delta=update.delta, dof=update.dof, nis=update.nis, apply_t=apply_t,
                       pose=se2.compose(update.delta, base_pose))

    def _is_jump(self, innovation: np.ndarray) -> bool:
        """Whether a refused registration's innovation (x, y, yaw) is as large as a jump (`lost_jump_m`,
        `lost_jump_rad`)."""
        p = self.params
        return bool(np.hypot(innovation[0], innovation[1]) >= p.lost_jump_m or abs(innovation[2]) >= p.lost_jump_rad)

    def _grow(self, innovation: np.ndarray | None) -> None:
        """A χ² refusal smaller than a jump that no moved object explains: the filter was too sure of itself, so P
        grows by the innovation and the next frame may pass."""
        if innovation is not None:
            with self.lock:
                self.filter.P = self.filter.P + np.diag(np.asarray(innovation, float) ** 2)

    def _assign(self, ref: Reference, target: registration.Target, world: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Each frame point (world, placed by a camera pose) to its nearest reference point: that point's index, its
        object's id, the distance (m), and whether it is near enough (< `radius_max_m`) to count."""
        idx, d = target.nearest(world)
        ids = ref.object_ids[np.clip(idx, 0, len(ref.object_ids) - 1)]
        return idx, ids, d, (idx >= 0) & (d < self.params.radius_max_m)

    def _object_residuals(self, ref: Reference, target: registration.Target, source, T: np.ndarray
                          ) -> dict[int, float]:
        """Per object with at least `min_object_points` frame points near it (camera pose T): the median distance
        (m) of those points from the reference: from the nearest sample, or with `disagreement_from_planes` from the
        side faces' planes only (`Target.side_offsets`). Side faces, as they pin the base's x, y and yaw and drag it
        when the object moved; from the plane, so that a far face seen obliquely or a face not yet mapped to its end
        does not read as moved (a newly mapped row read 4.1-4.4 cm from its samples at every frame of a lap's corner,
        was set aside and left the base with nothing to register against for 10 s). Points farther than
        `radius_max_m` from any sample are not judged here (`_looked_through` judges a face seen through from farther:
        docs/decisions.md, "A new row read as moved")."""
        p = self.params
        world = _placed(np.asarray(source.points())[:, :3], T)
        idx, ids, d, near = self._assign(ref, target, world)
        near &= ids >= 0  # objects only: not the floor, not unlabelled
        if p.disagreement_from_planes and np.any(near):
            offset, side = target.side_offsets(world[near], idx[near])
            return _median_per_object(ids[near][side], offset[side], p.min_object_points)
        return _median_per_object(ids[near], d[near], p.min_object_points)

    def _looked_through(self, ref: Reference, frame: DepthFrame, radius_m: float) -> dict[int, float]:
        """With `disagreement_from_planes`: the objects the frame, at the pose it was posed at (the prediction), looks
        through by more than the correspondence radius (`see_through.seen_through`), and the depth (m) by which it
        does. Farther than registration looks for partners, so no alignment can have brought them back: a 0.5 m
        slip toward a single wall puts the wall's points at the gate, where no residual judges them."""
        p = self.params
        if not p.disagreement_from_planes:
            return {}
        return see_through.seen_through(ref.points, ref.object_ids, frame, frame.T_world_camera, radius_m,
                                        p.max_range_m, p.min_object_points, p.see_through_share)

    def _disagreeing(self, ref: Reference, target: registration.Target, source, T: np.ndarray
                     ) -> tuple[int, ...] | None:
        """The objects whose frame points, placed by the camera pose T, sit farther than `disagreement_m` (median)
        from the reference; None when most of those judged do (then the pose, not the objects, is in doubt). The
        loop closure's vote (`loop_closure.py`)."""
        residual = self._object_residuals(ref, target, source, T)
        off = tuple(i for i, d in residual.items() if d > self.params.disagreement_m)
        return None if off and 2 * len(off) > len(residual) else off

    def _view_agrees(self, fit: dict[int, float]) -> bool:
        """Whether at least two objects were judged and every one fits at the registered pose (`fit`: residuals
        there): only a shift the whole view agrees on says the filter was too sure of itself. One object alone may be
        a box that moved out of view of anything else (a pick box moved 0.4 m at a lap's start, the only object in
        view, had P grown by its 0.3 m pull and the next frame took it: 22 cm off for the lap)."""
        return len(fit) >= 2 and all(d <= self.params.disagreement_m for d in fit.values())

    def _judge_objects(self, ref: Reference, target: registration.Target, source, frame: DepthFrame,
                       aligned: np.ndarray, radius_m: float, loop_vouches: bool = False) -> ObjectVerdict:
        """The objects off their surfaces, how many were judged, whether something vouched for the prediction,
        and the camera pose they were judged at. Objects are judged where the pose is best known: at the
        prediction when it is confident, else after the alignment; but a moved box within the correspondence
        radius drags the alignment, and when most of the view moved alike a vote after it finds the still box
        off (two of three boxes moved 0.07-0.12 m: the still one was left out and the two moved ones taken). So
        an object that fits the prediction and not the aligned pose vouches for the prediction: then the objects
        off at the prediction are the moved ones. A loop closure accepted within `loop_vouch_s` (`loop_vouches`)
        vouches for it too: the objects off are then ones the map placed while the pose drifted. The prediction is
        the camera pose `frame` (the depth frame of `source`) was posed at; it is confident when the correspondence
        radius is at its least. An object the prediction looks through beyond that radius is off at either pose."""
        p = self.params
        dm, confident = p.disagreement_m, radius_m <= p.radius_min_m + 1e-9
        predicted = frame.T_world_camera
        through = self._looked_through(ref, frame, radius_m)
        at_prediction = self._object_residuals(ref, target, source, predicted) | through
        if loop_vouches or confident:
            off = tuple(i for i, d in at_prediction.items() if d > dm)
            return ObjectVerdict(off, len(at_prediction), loop_vouches and bool(off), predicted)
        at_aligned = self._object_residuals(ref, target, source, aligned) | through
        vouched = any(d <= dm and at_aligned.get(i, math.inf) > dm for i, d in at_prediction.items())
        judged, T = (at_prediction, predicted) if vouched else (at_aligned, aligned)
        return ObjectVerdict(tuple(i for i, d in judged.items() if d > dm), len(judged), vouched, T)

    def set_aside(self, ids: Iterable[int], t: float) -> None:
        """Leave objects out of the reference until robot time t + `exclusion_s` (a registration's disagreeing objects;
        and, without handing them to the map as change evidence, those a search found no jump against:
        `lost.search_frame`)."""
        until = t + self.params.exclusion_s
        for i in ids:
            self._excluded[i] = max(self._excluded.get(i, -math.inf), until)

    def prepared_reference(self, surface: ReferenceSurface | None, centre_xy: np.ndarray
                           ) -> tuple[Reference, registration.Target, float]:
        """The reference and its prepared target, rebuilt only when the surface, the excluded objects or the
        base's 1 m cell change; the ms spent rebuilding (0 when kept)."""
        cell = tuple(np.floor(centre_xy).astype(int))
        version = None if self.frozen is None else self.frozen.version
        key = (None if surface is None else surface.t, version, frozenset(self._excluded), cell)
        cached = self._target
        # the surface itself is held and compared by identity: an id() in the key can match a new surface
        # that reuses a freed one's address (the same defect once made lockstep runs differ)
        if cached is not None and cached[0] is surface and cached[1] == key:
            return cached[2], cached[3], 0.0
        p = self.params
        ref = build(surface, np.floor(centre_xy) + 0.5, p.reference_crop_m, p.floor_step_m, self._excluded)
        target = registration.Target(ref.points)
        self._target = (surface, key, ref, target)
        return ref, target, target.ms

    def _record(self, correction: Correction) -> Correction:
        self.counts[correction.verdict.value] += 1
        self.corrections.append(correction)
        outcome = OUTCOMES.get(correction.verdict, "rejected")
        with self.lock:
            self.tally[outcome] += 1
            if correction.verdict == Verdict.ACCEPTED:
                self._accepted_t.append(correction.t)
                self.rest_s = 0.0
            if correction.verdict != Verdict.SEARCHED:
                self._last_verdict = (correction.t, correction.verdict)
            if self.lost.observe(correction.verdict, correction.t, self.status != LocalizationStatus.ODOMETRY,
                                 correction.jump, correction.off):
                self.status = LocalizationStatus.LOST
        return correction


def _placed(points_camera: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Camera-frame points placed in the world by the camera pose T (4x4)."""
    return points_camera @ T[:3, :3].T + T[:3, 3]


def _median_per_object(ids: np.ndarray, values: np.ndarray, min_points: int) -> dict[int, float]:
    """The median of `values` per object id with at least `min_points` of them."""
    residual: dict[int, float] = {}
    for i in np.unique(ids):
        mine = ids == i
        if np.sum(mine) >= min_points:
            residual[int(i)] = float(np.median(values[mine]))
    return residual


def _constrained_innovation(measured: np.ndarray, predicted: np.ndarray, dirs: degeneracy.Directions
                            ) -> np.ndarray:
    """measured ⊖ predicted (x, y, yaw) along the registration's constrained directions only."""
    nu = np.array([measured[0] - predicted[0], measured[1] - predicted[1], wrap_angle(measured[2] - predicted[2])])
    U = dirs.vectors[:, dirs.constrained]
    return np.linalg.inv(dirs.scale) @ U @ U.T @ dirs.scale @ nu
