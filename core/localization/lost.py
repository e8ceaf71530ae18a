"""Lost: registrations that keep disagreeing with the estimate (a slip, a kidnap), what becomes of the frames
meanwhile, and the global search that ends it (docs/method.md, "State estimation", "Lost"; issue 28, item 3).

- **Suspect.** A registration that had trusted surface in view and was refused by a gate (χ² with an innovation
  as large as a jump, inconsistent, few inliers) while the localizer was localized starts a streak (a χ² refusal
  smaller than `lost_jump_m` / `lost_jump_rad` says the filter was too sure of itself: P grows by the innovation
  and the frame is only in doubt); an accepted one, or one with nothing to judge (no
  reference, too few points), ends it. Degenerate and not converged ones neither start nor end it (a frame that fits
  the floor alone says nothing about a jump, and GICP stopping at its iteration cap says little).
- **Frames wait** (`LocalizationParams.hold_frames`): a frame is integrated only once a registration at or after its
  exposure found no jump (`confirmed_t`: accepted, nothing to judge, or, outside a streak, degenerate or not
  converged), and at once while the latest registration had no trusted surface in view (no verdict could refuse
  it; held, E3's frames waited up to 0.25 s and pushes 0.5 m ahead were hit); while a streak runs frames wait
  (and are dropped after `hold_max_s`, as are frames up to a refused one that no verdict confirmed); when the
  localizer gets lost, every frame not confirmed is dropped, and so is every frame until the re-anchoring has been
  applied: the map never integrates a frame at a pose that has jumped where a registration could tell.
- **Lost.** A streak of at least `lost_min_refusals` refusals over at least `lost_after_s`: the loop holds the base
  (brakes to rest and plans nothing), and once the base is at rest each frame the localizer wants runs a global
  search (`global_search.py`) instead of a registration, one at a time, its outcome due `search_processing_s` after
  the frame. A unique answer
  re-anchors T_world←odom (P restarts at `search_sigma_m` / `search_sigma_rad`) and, once applied, the run goes on.
  First, though: if the estimate itself fits about as well as the best guess before registration, or the good
  fits lie along a corridor through it (`SearchResult.estimate_fits`: the refusals came from a drifted pose, not a
  jump), or if
  the frame fits the reference nowhere in the window (no registered guess scores `search_min_score`: the reference
  does not describe this view, and the frame cannot tell where the base is), the run goes on from the estimate.
  When the estimate fits, the objects the streak's inconsistent registrations found off their surfaces
  (`Episode.suspects`) are set aside (out of the reference for `exclusion_s`, not handed to the map as change
  evidence): the view disagreed with them, not with the pose, and without them the next frames of the same view can
  be confirmed and mapped instead of making the localizer lost again (E1's scene 8: seven times, then a fault;
  docs/decisions.md). Not when nothing fits: that frame tells nothing, about the objects either.
  An ambiguous search is tried again without those suspects, and when the estimate fits there the run goes on from
  it in the same way (boxes moved unseen and held at their old places made perfect fits elsewhere).
  Only ambiguity faults: after `search_tries` searches that found good fits at distinct poses, `failed` holds the
  reason ("lost localization: …") and the loop faults.

Thread use: every method is called under the localizer's lock.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from core.angles import wrap_angle
from core.localization import global_search, registration, scan, se2
from core.localization.frozen_surfaces import FrozenSurfaces
from core.localization.gates import Verdict
from core.localization.global_search import SearchResult
from core.localization.pose_filter import PoseFilter
from core.localization.reference import Reference
from core.params import LocalizationParams
from core.types import DepthFrame, ReferenceSurface

DISAGREEING = (Verdict.CHI2, Verdict.INCONSISTENT, Verdict.FEW_INLIERS)
"""Verdicts that say the frame does not fit where the estimate puts it. Not converged says little (on E4's aisle a
third of the registrations that were not accepted, in streaks of up to 3 while well localized), nor does degenerate:
neither starts nor ends a streak."""
UNJUDGED = (Verdict.NO_REFERENCE, Verdict.TOO_FEW_POINTS)
"""Verdicts with nothing to judge by: no evidence of a jump, the streak ends."""
REST_M = 0.005
REST_RAD = 0.005
"""The base is at rest for a search when it moved less than these (m, rad) between two frames offered (0.2 s apart at
5 Hz: 2.5 cm/s)."""
INTEGRATE, HOLD, DROP = "integrate", "hold", "drop"
"""What becomes of a frame (`LostWatch.fate`)."""


@dataclass(frozen=True)
class Episode:
    """One lost episode: robot times (s) of the first refused frame, of getting lost, of the searches, and of the
    re-anchoring (nan: not re-anchored), the re-anchoring (world-frame Δ, x, y, yaw), and the searches' results."""

    refused_t: float
    lost_t: float
    searches: tuple[tuple[float, SearchResult], ...] = ()
    anchored_t: float = math.nan
    delta: np.ndarray | None = None
    suspects: tuple[int, ...] = ()
    """The objects the streak's inconsistent registrations found off their surfaces."""


class LostWatch:
    """The streak of disagreeing registrations, the lost state, the frames' fate, and the searches' bookkeeping."""

    def __init__(self, params: LocalizationParams) -> None:
        self.params = params
        self.streak: list[float] = []
        """Frame times of the refused registrations of the current streak."""
        self.confirmed_t = -math.inf
        """Frames exposed at or before this robot time (s) are confirmed: a later registration found no jump."""
        self.drop_until_t = -math.inf
        """Frames exposed at or before this robot time (s) are dropped (they may be at a pose that has jumped)."""
        self.doubted_t = -math.inf
        """Frame time (s) of the latest refused registration: unconfirmed frames up to it are in doubt."""
        self.lost = False
        self.busy_until_t = -math.inf
        """A search is under way (modelled, lockstep) until this robot time (s): no new one before."""
        self.resume_t: float | None = None
        """The re-anchoring applies at this robot time (s); lost until then."""
        self.resume_delta = np.zeros(3)
        """The re-anchoring: the world-frame correction Δ (x, y, yaw) applied to T_world←odom at `resume_t`."""
        self.failed: str | None = None
        """Why the localizer gave up ("lost localization: …"); the loop faults with it."""
        self.episodes: list[Episode] = []
        self.nothing_to_judge = False
        """The latest registration had nothing to judge by (no trusted surface in view): frames are not held."""
        self._last_pose: np.ndarray | None = None
        self._suspects: set[int] = set()
        """The objects the current streak's inconsistent registrations found off their surfaces."""

    @property
    def tries(self) -> int:
        return len(self.episodes[-1].searches) if self.lost and self.episodes else 0

    def observe(self, verdict: Verdict, t: float, localized: bool, jump: bool = True, off: Iterable[int] = ()) -> bool:
        """A registration's verdict for the frame exposed at t (`jump`: a χ² refusal's innovation is as large as a
        jump; `off`: the objects an inconsistent one found off their surfaces); whether the localizer got lost with
        it."""
        if self.lost:
            return False
        p = self.params
        self.nothing_to_judge = verdict in UNJUDGED
        if verdict == Verdict.CHI2 and not jump:  # the filter too sure, not a slip: its frames are in doubt only
            self.doubted_t = t
            return False
        if verdict in DISAGREEING and localized:
            self.streak.append(t)
            self._suspects.update(off)
            self.doubted_t = t
            if len(self.streak) >= p.lost_min_refusals and t - self.streak[0] >= p.lost_after_s - 1e-9:
                self.lost = True
                self.episodes.append(Episode(self.streak[0], t, suspects=tuple(sorted(self._suspects))))
                return True
        elif verdict == Verdict.ACCEPTED or verdict in UNJUDGED:
            self._end_streak()
            self.confirmed_t = max(self.confirmed_t, t)
        elif not self.streak:  # degenerate, not converged: no evidence of a jump, so none to wait for either
            self.confirmed_t = max(self.confirmed_t, t)
        elif t - self.streak[-1] > p.lost_after_s:
            self._end_streak()  # degenerate ever since: the refusals stopped (the frames held meanwhile are dropped)
        return False

    def _end_streak(self) -> None:
        self.streak = []
        self._suspects = set()

    def wants_search(self, t: float, base_pose: np.ndarray) -> bool:
        """Whether the frame exposed at t, the base at `base_pose` (by odometry) then, runs a search: lost, none under
        way, none succeeded, not failed, and the base at rest (it moved less than `REST_M` / `REST_RAD` since the last
        frame offered: a frame taken while braking is posed less well than one taken at rest)."""
        last, self._last_pose = self._last_pose, np.asarray(base_pose, float).copy()
        if not (self.lost and self.resume_t is None and self.failed is None and t >= self.busy_until_t - 1e-9):
            return False
        return last is not None and bool(np.hypot(*(base_pose[:2] - last[:2])) < REST_M
                                          and abs(wrap_angle(float(base_pose[2] - last[2]))) < REST_RAD)

    def searched(self, t: float, result: SearchResult) -> tuple[float, bool]:
        """Record a search of the frame exposed at t; the robot time its outcome is due, and whether it re-anchors
        at the best candidate (a unique answer where the estimate itself did not fit)."""
        p = self.params
        due = t + p.search_processing_s
        self.busy_until_t = due
        episode = self.episodes[-1]
        searches = (*episode.searches, (t, result))
        self.episodes[-1] = replace(episode, searches=searches)
        if result.estimate_fits or not result.fits:  # no jump after all, or nothing to tell: go on from the estimate
            self.resume_t = due
            self.resume_delta = np.zeros(3)
        elif result.unique and result.best is not None:
            self.resume_t = due
            return due, True
        elif len(searches) >= p.search_tries:
            self.failed = (f"lost localization: no unique pose in {len(searches)} global searches "
                           f"(±{p.search_xy_m:g} m, ±{math.degrees(p.search_yaw_rad):g}°; last: {result.reason})")
        return due, False

    def applied(self, t: float, delta: np.ndarray) -> None:
        """The re-anchoring (Δ) was applied at robot time t: found again; frames after it are mapped again once
        confirmed."""
        self.episodes[-1] = replace(self.episodes[-1], anchored_t=t, delta=np.asarray(delta, float))
        self.lost = False
        self.resume_t = None
        self._end_streak()
        self.drop_until_t = t
        self.confirmed_t = max(self.confirmed_t, t)

    def fate(self, frame_t: float, now: float) -> str:
        """What becomes of a frame exposed at frame_t, at robot time now: integrate, hold (wait for a verdict) or
        drop."""
        if frame_t <= self.drop_until_t + 1e-9 or (self.lost and frame_t > self.confirmed_t):
            return DROP
        if frame_t <= self.confirmed_t + 1e-9:
            return INTEGRATE
        if self.nothing_to_judge and not self.streak:  # no trusted surface in view: no verdict could refuse it
            return INTEGRATE
        if now - frame_t > self.params.hold_max_s:  # no verdict came: kept unless a refusal put it in doubt
            return DROP if self.streak or frame_t <= self.doubted_t else INTEGRATE
        return HOLD

    def reason(self) -> str | None:
        """The operator's line while lost (None otherwise)."""
        if self.failed is not None:
            return self.failed
        if not self.lost:
            return None
        if self.resume_t is not None:
            return "lost: found again, re-anchoring"
        return f"lost: searching (base held, mapping paused; {self.tries} of {self.params.search_tries} searches)"


class Searcher(Protocol):
    """What the search needs of the localizer (`Localizer`; a protocol, so that this module does not import it)."""

    params: LocalizationParams
    lock: threading.Lock
    lost: LostWatch
    frozen: FrozenSurfaces | None
    filter: PoseFilter

    def schedule(self, apply_t: float, delta: np.ndarray) -> None: ...

    def set_aside(self, ids: Iterable[int], t: float) -> None: ...

    def prepared_reference(self, surface: ReferenceSurface | None, centre_xy: np.ndarray
                           ) -> tuple[Reference, registration.Target, float]: ...


def search_frame(loc: Searcher, frame: DepthFrame, base_pose: np.ndarray, surface: ReferenceSurface | None
                 ) -> dict[str, Any]:
    """While lost (`Localizer.correct`): a global search of `frame` (posed by the current estimate, the base at
    `base_pose` then) against the floor and the trusted surfaces (the frozen ones when frozen), when one is due; a
    unique answer re-anchors T_world←odom at the frame's stamp + `search_processing_s` and restarts P. Returns the
    fields of the frame's `Correction` (verdict SEARCHED; `pose` and `apply_t` set when it re-anchors)."""
    p = loc.params
    with loc.lock:
        due = loc.lost.wants_search(frame.t, base_pose)
    if not due:
        return {}
    if loc.frozen is not None:
        surface = loc.frozen.surface
    ref, target, ref_ms = loc.prepared_reference(surface, base_pose[:2])
    source, _ = registration.thin(scan.camera_points(frame, p.stride_px, p.max_range_m), p.source_voxel_m)
    result = global_search.search(ref, target, source, frame.T_world_camera, base_pose, p)
    suspects = loc.lost.episodes[-1].suspects
    if suspects and surface is not None and result.fits and not (result.unique or result.estimate_fits):
        result = _without_suspects(loc, frame, base_pose, surface, source, suspects) or result
    with loc.lock:
        apply_t, reanchor = loc.lost.searched(frame.t, result)
        if result.estimate_fits:  # no jump after all: the objects the view disagreed with are set aside a while
            loc.set_aside(loc.lost.episodes[-1].suspects, frame.t)
        if not reanchor or result.best is None:  # (best is set whenever it re-anchors)
            return {"registration_ms": result.ms, "reference_ms": ref_ms}
        delta = se2.compose(result.best.pose, se2.inverse(base_pose))
        loc.lost.resume_delta = delta
        loc.filter.P = np.diag([p.search_sigma_m**2, p.search_sigma_m**2, p.search_sigma_rad**2])
        loc.schedule(apply_t, delta)
    return {"delta": delta, "dof": 3, "registration_ms": result.ms, "reference_ms": ref_ms, "apply_t": apply_t,
            "pose": result.best.pose}


def _without_suspects(loc: Searcher, frame: DepthFrame, base_pose: np.ndarray, surface: ReferenceSurface, source,
                      suspects: tuple[int, ...]) -> SearchResult | None:
    """An ambiguous search again without the objects the streak found off their surfaces: the search's result then
    when the estimate fits there (the view disagreed with those objects, not with the pose), else None. Boxes moved
    unseen, still held at their old places, made a search find two perfect fits 0.57 m apart, each 0.3-0.6 m from
    the truth, while the estimate was 6 cm off (E4's aisle, lap 2, localization on: the run faulted 'lost
    localization'). Only a way out of a false alarm: after a slip every object in view is off, and without them there
    is nothing to search against."""
    keep = ~np.isin(np.asarray(surface.object_ids), np.asarray(suspects))
    if keep.all():
        return None
    rest = ReferenceSurface(t=surface.t, points=np.asarray(surface.points)[keep],
                            object_ids=np.asarray(surface.object_ids)[keep])
    ref, target, _ = loc.prepared_reference(rest, base_pose[:2])
    result = global_search.search(ref, target, source, frame.T_world_camera, base_pose, loc.params)
    return result if result.estimate_fits else None
