"""Loop closure: a pose graph of keyframes, closed onto the places an earlier visit kept (docs/method.md, "State
estimation", "Loop closure").

Registering against the map's surfaces cannot bound the drift over laps: the map placed them with the drifting
pose, so a revisited place agrees with the drifted pose. Here the registered frames themselves are kept
(`keyframes.py`) as nodes of a pose graph (`pose_graph.py`) with
  - between consecutive nodes, their increment along the chain c = T_chain ∘ o (the wheel odometry o, with the map
    registrations' corrections composed into T_chain when `graph_follows_map`, else T_chain = identity), Ω from the
    odometry's random walk (σ_m² s, σ_r² |Δψ|): where no loop closes, the graph keeps the filter's trajectory; a
    closure bends it as the odometry's uncertainty allows,
  - the first node of a chain held by a prior with the filter's covariance then (the start, or a re-anchoring),
  - loop closures: a frame registered against the submap of the keyframes an earlier visit kept around the nearest
    of them (the anchor x_a), which gives x_b = x_a ∘ z with the registration's information (σ `loop_sigma_m` /
    `loop_sigma_rad` along its constrained directions).
The map's registrations do not enter the graph (as priors, even loose ones at 0.1–0.3 m, they held a lap's keyframes
where the drift had put them against the loop closure at its end: docs/decisions.md). Each loop closure optimises the
graph; T_world←odom then follows the optimised node of the frame, and P becomes that node's covariance in the graph.
The search radius of a loop closure is sized by how far the base may be from the anchor by the graph (their relative
covariance, not the filter's over-confident P; 3σ + margin, coarse then fine), so the end of a lap, far from where it
was, still finds the surfaces kept at its start. Gates as for the
map's registration (convergence, inlier share, degeneracy, χ²); objects whose points disagree with the submap
leave every keyframe and are handed to the map as change evidence.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, replace

import numpy as np

from core.angles import wrap_angle
from core.localization import gates, registration, scan, se2
from core.localization.correction import Correction
from core.localization.gates import Verdict
from core.localization.keyframes import Keyframes
from core.localization.measurement import Measurement, measure
from core.localization.odometry_prediction import predict_covariance
from core.localization.pose_filter import measurement_information, position_std
from core.localization.pose_graph import PoseGraph
from core.localization.reference import FLOOR_ID, Reference
from core.params import LocalizationParams
from core.types import DepthFrame

ODOMETRY, LOOP, ANCHOR = "odometry", "loop", "anchor"
"""Factor kinds: odometry between nodes, a loop closure, the prior of a chain's start."""


@dataclass(frozen=True)
class Closure:
    """One loop-closure attempt: the correction it makes (its verdict; when a factor went into the graph, the
    world-frame Δ and the node's optimised pose; NIS, dof, times, the objects that disagreed; `loop` set), the node's
    covariance P in the graph (None: no factor), and, accepted, the measurement (for the filter when no factor is
    due, `_factor_due`; with a factor, for tracing what the closure constrained)."""

    correction: Correction
    P: np.ndarray | None = None
    measurement: Measurement | None = None


class LoopClosure:
    """The pose graph, its keyframes and the loop closures onto them."""

    def __init__(self, params: LocalizationParams) -> None:
        self.params = p = params
        self.graph = PoseGraph()
        self.keyframes = Keyframes(p.keyframe_step_m, p.keyframe_step_rad)
        self._last: tuple[int, np.ndarray] | None = None
        """The latest node and the chain pose at it."""
        self._target: tuple[tuple, Reference, registration.Target] | None = None
        self.closures = 0
        self._last_factor: np.ndarray | None = None
        """The base pose of the latest loop-closure factor."""

    def break_chain(self) -> None:
        """The odometry jumped (a slip, re-anchored by a global search): the next node starts a new chain."""
        self._last = None

    # --- nodes ----------------------------------------------------------------------------------------------

    def node(self, pose: np.ndarray, chain: np.ndarray, P: np.ndarray) -> int:
        """A node at `pose` (world, the current estimate), tied to the latest by the increment of the chain pose
        `chain`; the first of a chain by a prior with the filter's covariance P."""
        p = self.params
        j = self.graph.add_node(pose)
        if self._last is None:
            self.graph.add_prior(j, pose, np.linalg.inv(P + 1e-12 * np.eye(3)), ANCHOR)
        else:
            i, chain_i = self._last
            z = se2.compose(se2.inverse(chain_i), chain)
            s, turn = float(np.hypot(z[0], z[1])), abs(float(z[2]))
            sm, sr = p.drift_m_per_sqrt_m, p.drift_rad_per_sqrt_rad
            var = np.array([sm**2 * s + p.graph_odometry_floor_m**2, sm**2 * s + p.graph_odometry_floor_m**2,
                            sr**2 * turn + p.graph_odometry_floor_rad**2])
            self.graph.add_between(i, j, z, np.diag(1.0 / var), ODOMETRY)
        self._last = (j, np.asarray(chain, float).copy())
        return j

    def after_map_registration(self, frame: DepthFrame, predicted: np.ndarray, pose: np.ndarray, chain: np.ndarray,
                               P: np.ndarray, points_camera: np.ndarray, ref: Reference, target: registration.Target
                               ) -> None:
        """After a registration against the map's surfaces (the frame posed at the base's `predicted` world pose,
        `pose` the pose after the registration): where the place has no keyframe yet, a node there, the frame's
        points on trusted surfaces kept as its keyframe."""
        p = self.params
        if self.keyframes.covered(self.graph.x, pose):
            return
        T = se2.to_matrix(se2.compose(pose, se2.inverse(predicted))) @ frame.T_world_camera  # the corrected camera
        world = points_camera @ T[:3, :3].T + T[:3, 3]
        idx, d = target.nearest(world)
        ids = ref.object_ids[np.clip(idx, 0, len(ref.object_ids) - 1)]
        keep = (idx >= 0) & (d <= p.keyframe_label_m) & (ids >= 0) & (world[:, 2] > p.keyframe_floor_m)
        if np.sum(keep) < p.min_object_points:
            return
        j = self.node(pose, chain, P)
        base = se2.to_matrix(se2.inverse(pose))
        self.keyframes.add(j, frame.t, world[keep] @ base[:3, :3].T + base[:3, 3], ids[keep])

    # --- loop closures --------------------------------------------------------------------------------------

    def close(self, anchor: int, frame: DepthFrame, base_pose: np.ndarray, chain: np.ndarray, P: np.ndarray,
              source, live_ids: Collection[int], judge) -> Closure | None:
        """Register `frame` (posed by the current estimate; the base at `base_pose`) against the keyframes an earlier
        visit kept around `anchor` (`anchor()`); None when too few of them are in view (the map's surfaces are then
        the reference). `source`: the frame's thinned points; `judge(ref, target, source, T)`: the objects that
        disagree (None: most of them)."""
        p = self.params
        ref, target, ref_ms = self._prepared(anchor, frame.t, live_ids, base_pose)
        trusted = ref.object_ids != FLOOR_ID
        if np.sum(scan.in_view(ref.points[trusted], frame, p.max_range_m)) < p.min_trusted_points:
            return None
        sigma_P = self._honest(self.keyframes.frames[anchor].node, chain)
        sigma = position_std(sigma_P, p.max_range_m / 2)
        radius = float(np.clip(p.radius_sigmas * sigma + p.radius_margin_m, p.radius_min_m, p.loop_radius_max_m))
        T0 = frame.T_world_camera
        ms = 0.0
        if radius > p.loop_fine_radius_m:
            coarse = registration.register(target, source, T0, radius, p.max_iterations)
            ms += coarse.ms
            T0 = coarse.T_world_camera
        result = registration.register(target, source, T0, min(radius, p.loop_fine_radius_m), p.max_iterations)
        ms += result.ms
        disagreeing = judge(ref, target, source, result.T_world_camera)
        if disagreeing is None:
            return Closure(Correction(frame.t, Verdict.INCONSISTENT, registration_ms=ms, reference_ms=ref_ms,
                                      loop=True))
        if disagreeing:
            self.keyframes.forget(disagreeing)
            ref, target, more = self._prepared(anchor, frame.t, [i for i in live_ids if i not in disagreeing],
                                               base_pose)
            ref_ms += more
            result = registration.register(target, source, T0, min(radius, p.loop_fine_radius_m), p.max_iterations)
            ms += result.ms
        base = Correction(frame.t, Verdict.ACCEPTED, registration_ms=ms, reference_ms=ref_ms,
                          disagreeing=tuple(disagreeing), inlier_share=result.inliers / max(result.source_points, 1),
                          loop=True)
        m = measure(result, frame, base_pose, np.asarray(source.points())[:, :3], p)
        if not isinstance(m, Measurement):
            return Closure(replace(base, verdict=m))
        measured, dirs = m.pose, m.directions
        Hm, R = measurement_information(dirs, p.loop_sigma_m, p.loop_sigma_rad, 5.0 * p.degenerate_information)
        nu = np.array([measured[0] - base_pose[0], measured[1] - base_pose[1], wrap_angle(measured[2] - base_pose[2])])
        y = Hm @ nu
        nis = float(y @ np.linalg.solve(Hm @ sigma_P @ Hm.T + R, y))
        base = replace(base, dof=dirs.dof, nis=nis)
        if not gates.chi2_passes(nis, dirs.dof, p):
            return Closure(replace(base, verdict=Verdict.CHI2))
        if not self._factor_due(base_pose):
            return Closure(base, measurement=m)
        self._last_factor = np.asarray(base_pose, float).copy()
        info_world = Hm.T @ np.linalg.solve(R, Hm)
        a = self.keyframes.frames[anchor].node
        j = self.node(base_pose, chain, P)
        xa = self.graph.x[a]
        R3 = np.eye(3)
        R3[:2, :2] = se2.rot(float(xa[2]))
        self.graph.add_between(a, j, se2.compose(se2.inverse(xa), measured), R3.T @ info_world @ R3, LOOP)
        self.graph.optimize(p.graph_iterations)
        self.closures += 1
        pose = self.graph.x[j].copy()
        P_new = self.graph.marginal(j)
        delta = se2.compose(pose, se2.inverse(base_pose))
        return Closure(replace(base, delta=delta, pose=pose), P=P_new, measurement=m)

    def anchor(self, pose: np.ndarray, t: float) -> int | None:
        """The keyframe (index) of an earlier visit nearest to `pose` at robot time t, if one is in reach."""
        p = self.params
        if self.graph.size == 0:
            return None
        return self.keyframes.anchor(self.graph.x, pose, t, p.loop_min_age_s, p.loop_search_m, p.loop_search_rad)

    def _factor_due(self, pose: np.ndarray) -> bool:
        """A loop closure adds a factor (and a node) once the base moved `keyframe_step_m` / `keyframe_step_rad` from
        the last one's: frames of a base standing still are one measurement, not many. (A factor every 2 s while
        standing, the fourth round's rule, tied each to the last by a near-zero increment at the odometry's floor, and
        each re-stated the one view's constraint: in the corridor test a second factor from the same place moved the
        direction the view does not constrain, 16 -> 23 cm off; docs/decisions.md.)"""
        if self._last_factor is None:
            return True
        p = self.params
        x0 = self._last_factor
        return (float(np.hypot(*(pose[:2] - x0[:2]))) >= p.keyframe_step_m
                or abs(wrap_angle(float(pose[2] - x0[2]))) >= p.keyframe_step_rad)

    def _honest(self, anchor: int, chain: np.ndarray) -> np.ndarray:
        """How far the base now may be from where the anchor's node puts it: the covariance of the latest node relative
        to the anchor's in the graph, grown by the odometry since."""
        p = self.params
        last = self._last if self._last is not None else (self.graph.size - 1, chain)
        P = self.graph.relative(anchor, last[0])
        return predict_covariance(P, last[1], chain, 0.0, p.drift_m_per_sqrt_m, p.drift_rad_per_sqrt_rad)

    def _prepared(self, anchor: int, t: float, live_ids: Collection[int], centre: np.ndarray
                  ) -> tuple[Reference, registration.Target, float]:
        """The submap around the anchor as a registration target, rebuilt only when its key changes."""
        p = self.params
        ref, key = self.keyframes.submap(self.graph.x, anchor, t, p.loop_min_age_s, p.loop_submap_m, live_ids,
                                         p.source_voxel_m, np.floor(np.asarray(centre[:2], float)) + 0.5,
                                         p.reference_crop_m, p.floor_step_m)
        if self._target is not None and self._target[0] == key:
            return self._target[1], self._target[2], 0.0
        target = registration.Target(ref.points)
        self._target = (key, ref, target)
        return ref, target, target.ms


