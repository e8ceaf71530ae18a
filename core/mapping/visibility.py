"""Expected-visible surface of an object, checked against a depth image (POCD's forced outlier).

Each surface point of an object's submap is projected into the frame and its expected depth z is
compared with the measured depth d at its pixel (margin m = visibility margin + 3 · c · z², the
depth noise model):

- outside the image, behind the camera or beyond the range: not expected (no evidence);
- |d − z| ≤ m: **hit**, the surface was seen where the map has it;
- every returning pixel within `patch_px` of its pixel reads beyond z + m: **through**, free space was
  seen through the place of the surface: evidence that the object is gone;
- d < z − m: **occluded** by something in front (or by the object's own near side): no evidence;
- no return at its pixel (d = 0): **unseen**: expected, but not observed; unless the floor along that
  ray lies beyond the range: then nothing could have returned from behind the point either, so the point
  is not expected from here (a place seen against the far floor is judged by the rays that do reach the
  floor within range, not outvoted by those that cannot);
- otherwise: its own pixel reads beyond but a neighbour does not (a grazing surface, see below):
  **hit**.

No evidence from nothing: a pixel that returns nothing is not evidence that space is free. Dark,
shiny and transparent surfaces return nothing, and so do random dropouts and everything beyond the
range: a box whose surface stops returning depth (or a camera that loses it) must not be removed, nor
carved. Unseen points count in an object's expected-visible surface, so the fraction of it seen through
(`VisibilityCounts.through_fraction`, which gates the forced outlier) is the fraction with real returns
from behind it: a dark box in plain view has only a rim seen through (its silhouette is a pixel or two
off its mapped surface) and keeps its belief; a box taken away is seen through wherever the floor or
something else returns behind its place. Beyond the range and above the horizon nothing returns, so a
place seen only against the sky gives no evidence at all: it is noticed from where the floor shows
behind it (`bench/mapping_rate.py` measures how fast).

The patch matters on surfaces seen at a grazing angle (a wall along the corridor the robot drives
down): a surface voxel whose centroid sits a centimetre or two off the true surface projects onto a
pixel whose ray meets the surface far behind it (the offset divided by the tangent of the grazing
angle), so a one-pixel test calls a wall that is there "seen through" and the object would be
removed or carved. A neighbour k pixels away meets the surface about k · z / f nearer along the
surface, so ±2 pixels absorb centimetre offsets at the depth range whatever the angle; a box that
is really gone is seen through over its whole silhouette but a thin rim. Only the points that fail
the one-pixel test pay for the patch.

A return from the floor (below the floor filter's threshold, `floor.py`) counts as no return: the ray
went past whatever the map has above the floor there. Without this the bottom rim of a box that was
taken away is "hit" by the floor just behind it, and stays in the map for ever.

Only "through" points count against an object, so unseen and occluded objects keep their belief.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.mapping.floor import floor_threshold
from core.mapping.flying_pixels import EdgeFilter, neighbourhoods_at
from core.params import MappingParams
from core.types import DepthFrame

NOT_EXPECTED, HIT, THROUGH, OCCLUDED, UNSEEN = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class VisibilityCounts:
    """Per object and frame: surface points hit, seen through, occluded and unseen (no return), of `total`."""

    hit: int
    through: int
    occluded: int
    total: int
    unseen: int = 0

    @property
    def expected(self) -> int:
        """Points that should have been seen: in the frustum, within range, not occluded (seen or not)."""
        return self.hit + self.through + self.unseen

    @property
    def through_fraction(self) -> float:
        """Fraction of the expected-visible surface with free space seen through it (unseen points count
        against it: they might be a surface that returns nothing)."""
        return self.through / self.expected if self.expected else 0.0

    @property
    def through_of_returns(self) -> float:
        """Of the expected-visible points whose pixels returned depth, the fraction seen through."""
        returned = self.hit + self.through
        return self.through / returned if returned else 0.0


@dataclass(frozen=True)
class FrameView:
    """A depth frame prepared for many visibility queries: world → camera transform and margins."""

    depth: np.ndarray
    K: np.ndarray
    R_cw: np.ndarray
    t_cw: np.ndarray
    range_m: float
    margin_m: float
    noise_coeff_m: float
    patch_px: int = 2
    floor_height_m: float = -np.inf
    edges: EdgeFilter | None = None

    @classmethod
    def of(cls, frame: DepthFrame, params: MappingParams) -> FrameView:
        """The view of a frame with the mapping's margins; returns lower than the floor height (plus noise) are
        floor, i.e. no return, and so are mixed pixels at depth edges (the points' flying-pixel filter)."""
        R = frame.T_world_camera[:3, :3]
        t = frame.T_world_camera[:3, 3]
        p = params
        return cls(frame.depth, frame.K, R.T, -R.T @ t, min(p.range_m, frame.range_m), p.visibility_margin_m,
                   p.depth_noise_coeff_m, p.through_patch_px, p.floor_height_m, EdgeFilter.of(p))

    @property
    def camera_position(self) -> np.ndarray:
        return -self.R_cw.T @ self.t_cw

    def may_see(self, centre: np.ndarray, radius: float) -> bool:
        """Cheap cull: could a sphere (world centre, radius) be partly in the frustum and in range?"""
        c = self.R_cw @ centre + self.t_cw
        if c[2] + radius <= 0.0 or c[2] - radius > self.range_m:
            return False
        h, w = self.depth.shape
        fx, fy = self.K[0, 0], self.K[1, 1]
        half_x = (w / 2) / fx
        half_y = (h / 2) / fy
        z = max(c[2], 1e-6)
        slack = radius * np.sqrt(1.0 + max(half_x, half_y) ** 2)
        return abs(c[0]) <= half_x * z + slack and abs(c[1]) <= half_y * z + slack

    def classify(self, points: np.ndarray) -> np.ndarray:
        """Label every world point (N×3): NOT_EXPECTED, HIT, THROUGH, OCCLUDED or UNSEEN."""
        labels = np.zeros(len(points), dtype=np.int8)
        if len(points) == 0:
            return labels
        p = points @ self.R_cw.T + self.t_cw
        z = p[:, 2]
        h, w = self.depth.shape
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.rint(self.K[0, 0] * p[:, 0] / z + self.K[0, 2])
            v = np.rint(self.K[1, 1] * p[:, 1] / z + self.K[1, 2])
        margin = self.margin_m + 3.0 * self.noise_coeff_m * z**2
        inside = (z > 0.0) & (u >= 0) & (u < w) & (v >= 0) & (v < h) & (z + margin < self.range_m)
        idx = np.nonzero(inside)[0]
        vi, ui = v[idx].astype(int), u[idx].astype(int)
        raw = self.returns_at(vi, ui)
        d = self.beyond_floor(raw, vi, ui)
        zi, mi = z[idx], margin[idx]
        lab = np.full(len(idx), HIT, dtype=np.int8)
        lab[d < zi - mi] = OCCLUDED
        silent = raw <= 0.0  # no return is no evidence, of the surface or of free space ...
        lab[silent] = UNSEEN
        # ... and where nothing could return behind the point either (the floor along its ray lies beyond the
        # range), the point cannot be seen through from here: it is not expected, not counted against
        lab[silent & ~self.floor_within_range(vi, ui)] = NOT_EXPECTED
        beyond = np.nonzero((d > zi + mi) & (raw > 0.0))[0]
        if len(beyond):
            near = self.patch_min(vi[beyond], ui[beyond])
            lab[beyond[near > zi[beyond] + mi[beyond]]] = THROUGH
        labels[idx] = lab
        return labels

    def returns_at(self, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Depths (m) of pixels (v, u), 0 where nothing returned or the pixel is mixed at a depth edge: a
        flying pixel hangs between the two sides, where nothing is (the points leave it out, so must this)."""
        raw = self.depth[v, u].astype(float)
        if self.edges is None:
            return raw
        return np.where(self.edges.mixed(raw, neighbourhoods_at(self.depth, v, u)), 0.0, raw)

    def ray_dz(self, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """World z change per metre of depth along the rays of pixels (v, u)."""
        K, R = self.K, self.R_cw
        return R[0, 2] * (u - K[0, 2]) / K[0, 0] + R[1, 2] * (v - K[1, 2]) / K[1, 1] + R[2, 2]

    def beyond_floor(self, d: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Depths (m) at pixels (v, u) with no return and floor returns made infinite (a floor return is free
        space seen up to the floor: beyond whatever the map has above it)."""
        ray_dz = self.ray_dz(v, u)
        height = self.camera_position[2] + d * ray_dz
        floor = height <= floor_threshold(d, ray_dz, self.floor_height_m, self.noise_coeff_m)
        return np.where((d > 0.0) & ~floor, d, np.inf)

    def floor_within_range(self, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Would the rays of pixels (v, u) meet the floor within the range? (Always, without a floor height:
        then every silent pixel is unseen, as before the floor was known.)"""
        if not np.isfinite(self.floor_height_m):
            return np.ones(len(v), bool)
        ray_dz = self.ray_dz(v, u)
        drop = self.floor_height_m - self.camera_position[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(ray_dz < 0.0, drop / ray_dz, np.inf)
        return depth < self.range_m

    def patch_min(self, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Nearest return (m) within ±`patch_px` pixels of each pixel (v, u); the floor counts as infinitely far,
        and so do pixels without a return (they say nothing, so they cannot hold a surface point back from
        being seen through by its returning neighbours)."""
        r = self.patch_px
        h, w = self.depth.shape
        off = np.arange(-r, r + 1)
        vv = np.clip(v[:, None, None] + off[None, :, None], 0, h - 1)
        uu = np.clip(u[:, None, None] + off[None, None, :], 0, w - 1)
        d = self.beyond_floor(self.depth[vv, uu].astype(float), vv, uu)
        return d.reshape(len(v), -1).min(axis=1)


def count(labels: np.ndarray) -> VisibilityCounts:
    """Tally of a label array from `FrameView.classify`."""
    n = np.bincount(labels, minlength=5)
    return VisibilityCounts(hit=int(n[HIT]), through=int(n[THROUGH]), occluded=int(n[OCCLUDED]), total=len(labels),
                            unseen=int(n[UNSEEN]))
