"""One object of the object-level map while it is being tracked: frame, submap, belief, counts.

The object frame T_world_object (yaw and translation) is fixed to the body: registration moves it,
the submap M_i lives in it. The published pose and extent are the upright box fitted to the submap
in that frame (what was seen), refitted whenever the submap changes. Whether that box stands for the
object (a box, or touching boxes that make one) or only bounds it (the L- or ring-shaped rows of an
aisle) is decided by the object's `Footprint`: only a box-like object is solid in the EDF and has its
unseen box faces count as its surface. For those, its `solid` box is the fit completed where it was
not seen (`completion.py`: an assumed depth behind a face seen from one side, down to the floor, each
cut short by free space seen there): the EDF, the association and the consistency update use it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Flag, auto

import numpy as np

from core.mapping.box_fit import BoxFit, fit_upright_box, seen_sides
from core.mapping.completion import Completion
from core.mapping.footprint import Footprint
from core.mapping.submap import ObjectSubmap
from core.types import MappedObject, ObjectStatus, Posterior

REFIT_CHANGE = 0.03
"""Refit the box's extent when the submap's voxel count, or the count of its well-supported voxels, changed by
more than this fraction."""
REFIT_YAW_GROWTH = 1.0
"""Refit its yaw (`box_yaw.side_yaw`) only when the submap grew by more than this fraction."""


class _Change(Flag):
    """What changed about an object, for `TrackedObject._invalidate`."""

    SURFACE = auto()
    """Points were added to the submap."""
    CARVED = auto()
    """Submap voxels were carved away: the box is refitted from scratch, yaw included."""
    POSE = auto()
    """Registration moved the object frame."""
    REFIT = auto()
    """The box was refitted."""
    SIDES = auto()
    """Completion evidence changed (a camera saw it, samples were seen through or hit)."""


@dataclass(frozen=True)
class _Shape:
    """The box fitted to the submap and what is decided with it (object frame)."""

    fit: BoxFit
    footprint: Footprint
    box_like: bool
    """Every point of the footprint lies within `box_fill_max_m` of the seen surface."""
    sides_seen: np.ndarray
    """Which side faces of the fit the well-supported voxels show (`seen_sides`)."""


def noise_weight(points_world: np.ndarray, camera_world: np.ndarray, near_m: float = 0.5) -> np.ndarray:
    """Inverse depth-noise variance of points seen from a camera, relative to a return at 1 m: depth noise
    grows as range² (σ = c z²), so a return at 3 m weighs 1/81 of one at 1 m (ranges under `near_m` count
    as `near_m`)."""
    r = np.maximum(np.linalg.norm(points_world - np.asarray(camera_world)[None, :3], axis=1), near_m)
    return 1.0 / r**4


def yaw_pose(yaw: float, position: np.ndarray) -> np.ndarray:
    """4×4 pose of a rotation by `yaw` about z and a translation."""
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = position
    return T


class TrackedObject:
    """Mutable state of one mapped object (the map's own bookkeeping; snapshots are `MappedObject`s)."""

    def __init__(self, object_id: int, points_world: np.ndarray, voxel_m: float, prior: Posterior,
                 floor_snap_m: float, box_fill_max_m: float = np.inf, completion: Completion | None = None,
                 camera_world: np.ndarray | None = None) -> None:
        self.id = object_id
        self.completion = completion or Completion(step_m=0.1, assumed_depth_m=0.0, confirm=3)
        """Cameras that saw the object and free space seen where its unseen parts could be."""
        self._solid_box: tuple[BoxFit, tuple[int, float], BoxFit] | None = None
        self.floor_snap_m = floor_snap_m
        self.box_fill_max_m = box_fill_max_m
        first = fit_upright_box(points_world, floor_z=0.0, floor_snap_m=floor_snap_m)
        self.T_world_object = yaw_pose(first.yaw, first.centre)
        self.submap = ObjectSubmap(voxel_m)
        self.posterior = prior
        self.observations = 1
        self.views: dict[str, int] = {}
        """Matched observations per camera: each camera's own count schedules its carving checks."""
        self.last_seen_t = float("nan")
        """Time (s) of the newest frame that observed the object (set by the mapper)."""
        self.first_seen_t = float("nan")
        self.first_camera = ""
        """When and by which camera the object was created (set by the mapper with `last_seen_t`)."""
        self.updates = 0
        self.status = ObjectStatus.ACTIVE
        self._shape: _Shape | None = None
        self._fit_voxels = -1
        self._fit_solid = -1
        self._surface_version = 0
        """Counts integrations and carvings: the well-supported voxels are counted again only when it changed."""
        self._checked_version = -1
        self._yaw: float | None = None
        self._yaw_voxels = 0
        self._world_points: np.ndarray | None = None
        self._bounds: np.ndarray | None = None
        self._grown: dict[float, Footprint] = {}
        self._interior: np.ndarray | None = None
        self.hollow = False
        """Free space was seen inside its fitted box: the box does not stand for the object (sticky)."""
        self.integrate(points_world, camera_world)

    # --- frames -----------------------------------------------------------------------------------

    def to_object(self, points_world: np.ndarray) -> np.ndarray:
        R, t = self.T_world_object[:3, :3], self.T_world_object[:3, 3]
        return (points_world - t) @ R

    def move(self, T_world_delta: np.ndarray) -> None:
        """Apply a world-frame motion of the body (from registration)."""
        self.T_world_object = T_world_delta @ self.T_world_object
        self._invalidate(_Change.POSE)

    # --- submap -----------------------------------------------------------------------------------

    def integrate(self, points_world: np.ndarray, camera_world: np.ndarray | None = None,
                  weights: np.ndarray | None = None) -> None:
        """Add an observation's points to the submap, weighted by their depth noise when the camera is given."""
        if weights is None and camera_world is not None:
            weights = noise_weight(points_world, camera_world)
        self.submap.integrate(self.to_object(points_world), weights)
        self._invalidate(_Change.SURFACE)

    def absorb(self, other: TrackedObject) -> None:
        """Take over the surface of another object (a duplicate of part of this one)."""
        self.integrate(other.world_points, weights=other.submap.weights)
        self.observations = max(self.observations, other.observations)
        R, t = other.T_world_object[:3, :3], other.T_world_object[:3, 3]
        for camera in other.completion.cameras:
            self.saw_from(R @ camera + t)

    def carve(self, min_misses: int) -> int:
        """Drop submap voxels repeatedly seen through; returns how many went."""
        n = self.submap.carve(min_misses)
        if n:
            self._invalidate(_Change.CARVED)
        return n

    def _invalidate(self, change: _Change) -> None:
        """Drop what `change` makes stale: the one place that knows which cache depends on what."""
        if change & (_Change.SURFACE | _Change.CARVED):
            self._surface_version += 1
        if change & (_Change.SURFACE | _Change.CARVED | _Change.POSE):
            self._world_points = None
        if change & (_Change.SURFACE | _Change.CARVED | _Change.POSE | _Change.SIDES):
            self._bounds = None
        if change & (_Change.POSE | _Change.REFIT):
            self._interior = None
        if change & _Change.CARVED:
            self._shape, self._yaw = None, None
        if change & _Change.REFIT:
            self._grown = {}

    @property
    def world_points(self) -> np.ndarray:
        """Submap surface points (V×3) in the world."""
        if self._world_points is None:
            R, t = self.T_world_object[:3, :3], self.T_world_object[:3, 3]
            self._world_points = self.submap.points @ R.T + t
        return self._world_points

    def distance(self, points_world: np.ndarray, upper_m: float) -> np.ndarray:
        """Distance (m, at most `upper_m`) of world points to the object: to its submap surface M_i or to
        the faces of its solid box, whichever is nearer (faces never seen, e.g. behind an occluder,
        are still the object's)."""
        local = self.to_object(points_world)
        d = self.submap.distance(local, upper_m)
        if self.box_like:
            d = np.minimum(d, np.abs(self._box_signed_distance(local)))
        return d

    # --- box --------------------------------------------------------------------------------------

    def _solid(self) -> np.ndarray:
        """Mask of the well-supported submap voxels: at least a quarter of the median point count (the
        rest are depth-noise outliers off the surface)."""
        counts = self.submap.counts
        return counts >= 0.25 * np.median(counts)

    def solid_world_points(self) -> np.ndarray:
        """The well-supported surface voxels (V×3) in the world."""
        return self.world_points[self._solid()]

    def solid_weights(self) -> np.ndarray:
        """The fused weight (V,) of each of `solid_world_points`."""
        return self.submap.weights[self._solid()]

    def _current_shape(self) -> _Shape:
        """The box fitted to the submap's well-supported voxels, refitted first if the submap changed.

        Voxels holding fewer than a quarter of the median point count are depth-noise outliers of
        the surface and are left out. The extent is refitted when the voxel count changed by more than
        `REFIT_CHANGE` since the last fit, the yaw when it grew by `REFIT_YAW_GROWTH` (or voxels were carved).
        The well-supported voxels change without the voxel count: the median count grows where the cameras look
        now, and a surface seen only before (a moved box's old place, after its new place was fused into it)
        falls under the quarter; so a change of their count by `REFIT_CHANGE` refits too (a box pushed 0.5 m
        otherwise kept its 1 m extent over both places: the fit stayed as it was when the old place was still
        well supported).
        """
        n = len(self.submap)
        if self._shape is not None and self._checked_version == self._surface_version:
            return self._shape
        self._checked_version = self._surface_version
        solid = self._solid()
        n_solid = int(solid.sum())
        if self._shape is not None and abs(n - self._fit_voxels) <= REFIT_CHANGE * max(self._fit_voxels, 1) \
                and abs(n_solid - self._fit_solid) <= REFIT_CHANGE * max(self._fit_solid, 1):
            return self._shape
        self._fit_voxels, self._fit_solid = n, n_solid
        pts = self.submap.points[solid] if solid.sum() >= 4 else self.submap.points
        if self._yaw is None or n > (1.0 + REFIT_YAW_GROWTH) * self._yaw_voxels:
            self._yaw, self._yaw_voxels = None, n
        fit = fit_upright_box(pts, floor_z=-self.T_world_object[2, 3], floor_snap_m=self.floor_snap_m, yaw=self._yaw)
        self._yaw = fit.yaw
        footprint = Footprint.of(pts, self.submap.voxel_m)
        self._shape = _Shape(fit, footprint, footprint.box_gap(fit) <= self.box_fill_max_m, seen_sides(pts, fit))
        self._invalidate(_Change.REFIT)
        return self._shape

    @property
    def fit(self) -> BoxFit:
        """Upright box around the submap's well-supported voxels, in the object frame."""
        return self._current_shape().fit

    @property
    def box_like(self) -> bool:
        """Does the fitted box stand for the object (every point of its footprint within `box_fill_max_m`
        of the seen surface)? If not, the object is its surface, columns filled down to the floor."""
        return self._current_shape().box_like and not self.hollow

    @property
    def solid(self) -> BoxFit:
        """The fitted box completed where the object was not seen (object frame; `completion.py`)."""
        fit, floor_z = self.fit, -self.T_world_object[2, 3]
        key = (self.completion.version, floor_z)
        cached = self._solid_box
        # the cache holds the fit itself and compares identity: a key of id(fit) matched a new fit that
        # reused a freed one's address, and the stale box made runs differ from process to process
        if cached is None or cached[0] is not fit or cached[1] != key:
            self._solid_box = cached = (fit, key, self.completion.box(fit, floor_z))
        return cached[2]

    @property
    def solid_pose(self) -> np.ndarray:
        """World pose (4×4) of the solid box's centre."""
        return self.T_world_object @ self.solid.pose()

    def completion_samples(self) -> np.ndarray:
        """World points where free space, if seen, shortens the solid box (`Completion.samples`)."""
        local = self.completion.samples(self.fit, -self.T_world_object[2, 3])
        R, t = self.T_world_object[:3, :3], self.T_world_object[:3, 3]
        return local @ R.T + t

    def observed_by(self, camera: str) -> int:
        """Count one matched observation by `camera` (in `observations` and in that camera's own count); returns
        the camera's count. Checks scheduled on the shared count would lock onto one camera: a 20 Hz and a 10 Hz
        camera interleave with period 3, so every third observation is always the same one's."""
        self.observations += 1
        self.views[camera] = self.views.get(camera, 0) + 1
        return self.views[camera]

    def saw_from(self, camera_world: np.ndarray) -> None:
        """A camera at this world position observed the object (which sides were seen)."""
        self.completion.saw_from(self.to_object(np.asarray(camera_world, float)[None])[0])
        self._invalidate(_Change.SIDES)

    def mark_completion(self, samples_world: np.ndarray, through: np.ndarray, hit: np.ndarray) -> None:
        """Record which completion samples were seen through or hit in one frame."""
        self.completion.mark(self.to_object(samples_world), through, hit)
        self._invalidate(_Change.SIDES)

    @property
    def footprint(self) -> Footprint:
        """Occupied x-y cells of the surface in the object frame (refitted with the box)."""
        return self._current_shape().footprint

    def interior(self, step_m: float, inset_m: float) -> np.ndarray:
        """World points on a `step_m` grid inside the fitted box, at least `inset_m` from its faces (empty
        for a box thinner than that): where free space, if seen, shows the box is not the object."""
        if self._interior is None:
            fit = self.fit
            half = fit.half - inset_m
            if np.any(half <= 0.0):
                self._interior = np.zeros((0, 3))
            else:
                axes = [np.linspace(-h, h, max(2, int(np.ceil(2 * h / step_m)) + 1)) for h in half]
                grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
                local = grid @ fit.rotation.T + fit.centre
                R, t = self.T_world_object[:3, :3], self.T_world_object[:3, 3]
                self._interior = local @ R.T + t
        return self._interior

    def covers(self, points_world: np.ndarray, grow_m: float) -> np.ndarray:
        """Mask of world points within the object grown by `grow_m`: its box if box-like, else its
        footprint's columns (from the floor to the top of the surface)."""
        if self.box_like:
            return self.inside_box(points_world, grow_m)
        if grow_m not in self._grown:
            self._grown[grow_m] = self.footprint.grown(grow_m)
        return self._grown[grow_m].contains(self.to_object(points_world))

    @property
    def pose(self) -> np.ndarray:
        """World pose (4×4) of the fitted box's centre."""
        return self.T_world_object @ self.fit.pose()

    @property
    def extent(self) -> np.ndarray:
        return self.fit.extent

    def bounds(self) -> np.ndarray:
        """World axis-aligned bounds (2×3: lower, upper) of the solid box."""
        if self._bounds is None:
            pose = self.solid_pose
            reach = np.abs(pose[:3, :3]) @ self.solid.half
            self._bounds = np.array([pose[:3, 3] - reach, pose[:3, 3] + reach])
        return self._bounds

    def _box_signed_distance(self, local: np.ndarray) -> np.ndarray:
        """Signed distance of object-frame points to the solid box (negative inside)."""
        box = self.solid
        q = np.abs((local - box.centre) @ box.rotation) - box.half
        return np.sqrt(np.sum(np.maximum(q, 0.0) ** 2, axis=1)) + np.minimum(q.max(axis=1), 0.0)

    def inside_box(self, points_world: np.ndarray, grow_m: float) -> np.ndarray:
        """Mask of world points within the solid box grown by `grow_m`."""
        box = self.solid
        u = (self.to_object(points_world) - box.centre) @ box.rotation
        return np.all(np.abs(u) <= box.half + grow_m, axis=1)

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre and radius of a sphere around the solid box (for frustum culling)."""
        return self.solid_pose[:3, 3], 0.5 * float(np.linalg.norm(self.solid.extent))

    def snapshot(self) -> MappedObject:
        return MappedObject(id=self.id, pose=self.pose, extent=self.extent.copy(), points=self.world_points.copy(),
                            posterior=self.posterior, status=self.status, observations=self.observations,
                            last_seen_t=self.last_seen_t, first_seen_t=self.first_seen_t,
                            first_camera=self.first_camera, sides_seen=self._current_shape().sides_seen.copy())
