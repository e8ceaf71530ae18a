"""Plain data that crosses package boundaries inside `core` (docs/design.md, "Data that crosses boundaries").

Frozen dataclasses with numpy fields; no behaviour beyond cheap derived views, except
`LocalEDF`, whose trilinear `distance`/`gradient` are the interface the controller sees a map by.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Protocol, TypeGuard

import numpy as np

NQ = 9
"""Joints of the robot: q = [x, y, yaw, 6 arm joints]."""

Vec3 = tuple[float, float, float]


def vec3(values: Iterable[float]) -> Vec3:
    """Three floats from any three numbers (a list, an array, a GUI field): a typed (x, y, z)."""
    x, y, z = (float(v) for v in values)
    return x, y, z


@dataclass(frozen=True)
class RobotState:
    """Joint positions q[9] and velocities v[9] at time t (s)."""

    t: float
    q: np.ndarray
    v: np.ndarray


@dataclass(frozen=True)
class DepthFrame:
    """One depth image: metres, 0 where the sensor saw nothing within range.

    `K` is the 3×3 pinhole intrinsic matrix; `T_world_camera` maps camera coordinates
    (OpenCV convention: x right, y down, z forward) to the world.
    """

    t: float
    camera: str
    depth: np.ndarray
    K: np.ndarray
    T_world_camera: np.ndarray
    range_m: float = 3.0


@dataclass(frozen=True)
class Odometry:
    """Base pose estimate (x, y, yaw) and twist in the world frame, as wheel odometry reports it."""

    t: float
    pose: np.ndarray
    twist: np.ndarray


class PoseSource(StrEnum):
    """What the base pose a backend reports is (`Observation.pose_source`)."""

    ODOMETRY = "odometry"
    """Dead reckoning (wheel odometry) in its own frame, drifting: the runtime's localizer corrects it when
    localization is on (`LocalizationParams.enabled`)."""
    LOCALIZED = "localized"
    """Already localized by the robot itself (its own SLAM), in a world frame: used as it is, the runtime's
    localizer stays off for it."""


@dataclass(frozen=True)
class Observation:
    """What a robot backend reports each tick: joint state, the depth frames captured since last time."""

    state: RobotState
    frames: tuple[DepthFrame, ...]
    odometry: Odometry | None
    """None where no odometry is reported (frames handed to the map on their own)."""
    pose_source: PoseSource = PoseSource.ODOMETRY
    """What the state's base pose (and the frames' poses) are: odometry, or the robot's own localization."""

    def q_at(self, t: float) -> np.ndarray:
        """The configuration at time t (a frame's exposure), from the state and its velocity: a frame is up to a
        camera period older than the state that comes with it."""
        return self.state.q - self.state.v * (self.state.t - t)


class ObjectStatus(StrEnum):
    """Life cycle of a mapped object (POCD)."""

    ACTIVE = "active"
    REMOVED = "removed"


@dataclass(frozen=True)
class Posterior:
    """q(l, v) = N(l | mu, sigma^2) · Beta(v | alpha, beta) of one object (docs/method.md, eq. 1); a new
    object's prior is `MappingParams.prior()`."""

    mu: float
    sigma: float
    alpha: float
    beta: float

    @property
    def consistency(self) -> float:
        """E[v] = alpha / (alpha + beta)."""
        return self.alpha / (self.alpha + self.beta)


@dataclass(frozen=True)
class MappedObject:
    """An object of the object-level map: pose (4×4), extent (3, full size), surface points (P×3)."""

    id: int
    pose: np.ndarray
    extent: np.ndarray
    points: np.ndarray
    posterior: Posterior
    status: ObjectStatus = ObjectStatus.ACTIVE
    observations: int = 0
    last_seen_t: float = float("nan")
    """Time (s) of the newest frame that observed the object (matched it or created it)."""
    first_seen_t: float = float("nan")
    """Time (s) of the frame that created the object (to trace a phantom to the moment and camera it came from)."""
    first_camera: str = ""
    """The camera of the frame that created the object ('' not known)."""
    sides_seen: np.ndarray | None = None
    """Which side faces of its box its well-supported surface shows (2×2 bool: the box's x, y axes; −, + side);
    None: not known. An unseen side is only as far as the top was seen (`core.mapping.box_fit.seen_sides`)."""

    @property
    def consistency(self) -> float:
        """E[v] of the object's posterior."""
        return self.posterior.consistency


@dataclass(frozen=True)
class ObjectMapSnapshot:
    """The object map at time t: live objects, the ids removed so far, and of those the ones merged into another
    object (`merged_into`: merged id → the live object it ended up in)."""

    t: float
    objects: tuple[MappedObject, ...]
    removed_ids: tuple[int, ...] = ()
    merged_into: dict[int, int] = field(default_factory=dict)


@dataclass(frozen=True)
class UnknownSpace:
    """Floor the cameras should have seen and did not (docs/method.md, "Unknown space is not free"): square
    cells `cell_m` wide centred at `centres` (K×2, world x-y) where the rays that should have met the floor
    within range returned no depth (a black, glossy or glass surface is in the way), each a column from the
    floor up to `height_m`. The planner and the operator's notice read it; the controller sees it inside the
    `LocalEDF` it comes with."""

    centres: np.ndarray
    cell_m: float
    height_m: float

    def distance(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (m) from points p (..., 3) to the nearest unknown column (0 inside; inf without cells) and
        that nearest point of the columns (..., 3)."""
        p = np.asarray(p, dtype=float)
        if len(self.centres) == 0:
            return np.full(p.shape[:-1], np.inf), p.copy()
        half = self.cell_m / 2
        xy = np.clip(p[..., None, :2], self.centres - half, self.centres + half)  # nearest point of each cell
        d_xy = np.sum((p[..., None, :2] - xy) ** 2, axis=-1)
        k = np.argmin(d_xy, axis=-1)
        nearest_xy = np.take_along_axis(xy, k[..., None, None], axis=-2)[..., 0, :]
        z = np.clip(p[..., 2:], 0.0, self.height_m)  # every column spans the same heights
        nearest = np.concatenate([nearest_xy, z], axis=-1)
        return np.linalg.norm(p - nearest, axis=-1), nearest

    def points(self, z_m: float) -> np.ndarray:
        """The cells' centres at height `z_m` (K×3), e.g. as occupied points for the planner."""
        return np.column_stack([self.centres, np.full(len(self.centres), z_m)])


@dataclass(frozen=True)
class LocalEDF:
    """Signed Euclidean distance field on a regular grid (docs/method.md, 9a–9b).

    `values[i, j, k]` is the distance (m) at `origin + voxel * (i, j, k)`, truncated at `cutoff`;
    outside the grid the field is `cutoff` with zero gradient. Queries are vectorised: `p` is (..., 3).
    """

    origin: np.ndarray
    voxel: float
    values: np.ndarray
    cutoff: float
    unknown: UnknownSpace | None = None
    """The unknown space the field already holds as obstacles (None: the map does not track it)."""

    def _cell(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The corner values (..., 2, 2, 2) of the cell holding each point (indexed [z, y, x]), the point's
        fraction (..., 3) across it, and whether it is inside the grid: one flat gather of the 8 corners."""
        g = (np.asarray(p, dtype=float) - self.origin) / self.voxel
        values = self.values
        shape = np.array(values.shape)
        inside = np.all((g >= 0.0) & (g <= shape - 1), axis=-1)
        i0 = np.clip(np.floor(g), 0, np.maximum(shape - 2, 0))
        f = np.clip(g - i0, 0.0, 1.0)
        grid = np.ascontiguousarray(values)
        stride = np.array(grid.strides) // grid.itemsize  # elements per cell step along x, y, z
        pick = np.arange(2)
        corner = pick[:, None, None] * stride[2] + pick[None, :, None] * stride[1] + pick[None, None, :] * stride[0]
        first = i0.astype(np.intp) @ stride
        return grid.reshape(-1)[first[..., None, None, None] + corner], f, inside

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Trilinearly interpolated distance at points p (..., 3) → (...)."""
        c, f, inside = self._cell(p)
        return np.where(inside, _lerp_z(_lerp_y(_lerp_x(c, f), f), f), self.cutoff)

    def gradient(self, p: np.ndarray) -> np.ndarray:
        """Gradient of the trilinear interpolant at points p (..., 3) → (..., 3), per metre."""
        return self.distance_and_gradient(p)[1]

    def distance_and_gradient(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`distance(p)` and `gradient(p)` from one cell lookup (half the work of the two calls)."""
        c, f, inside = self._cell(p)
        along_x = _lerp_x(c, f)  # (..., z, y)
        along_xy = _lerp_y(along_x, f)  # (..., z)
        d = _lerp_z(along_xy, f)
        dx = _lerp_z(_lerp_y(c[..., 1] - c[..., 0], f), f)
        dy = _lerp_z(_lerp_x(c[..., 1, :] - c[..., 0, :], f), f)
        dz = along_xy[..., 1] - along_xy[..., 0]
        grad = np.stack([dx, dy, dz], axis=-1) / self.voxel
        return np.where(inside, d, self.cutoff), np.where(inside[..., None], grad, 0.0)

    @property
    def upper(self) -> np.ndarray:
        """Far corner of the grid (m)."""
        return self.origin + self.voxel * (np.array(self.values.shape) - 1)


def _lerp_x(c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Linear interpolation over the last axis (x, of 2) at the fraction f[..., 0]."""
    fx = f[..., 0].reshape(f.shape[:-1] + (1,) * (c.ndim - f.ndim))
    return c[..., 0] * (1 - fx) + c[..., 1] * fx


def _lerp_y(c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Linear interpolation over the last axis (y, of 2) at the fraction f[..., 1]."""
    fy = f[..., 1].reshape(f.shape[:-1] + (1,) * (c.ndim - f.ndim))
    return c[..., 0] * (1 - fy) + c[..., 1] * fy


def _lerp_z(c: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Linear interpolation over the last axis (z, of 2) at the fraction f[..., 2]."""
    return c[..., 0] * (1 - f[..., 2]) + c[..., 1] * f[..., 2]


@dataclass(frozen=True)
class BaseReference:
    """Base task reference over the horizon: xy (K×2, m) and yaw (K, rad) or None for position only.

    K is N+1 (one row per node) or 1 (a constant reference for every node).
    """

    xy: np.ndarray
    yaw: np.ndarray | None = None


@dataclass(frozen=True)
class EEReference:
    """End-effector reference over the horizon: position (K×3, m), rotation (K×3×3) or None.

    `frame` 'world' (default) or 'base': a pose in the base frame (x ahead, z up from the floor) that the
    hand holds relative to the base wherever the base goes; the controller computes the error in the base
    frame at every node (`core.htmpc.task_costs.EEBaseFrameTaskCost`)."""

    position: np.ndarray
    rotation: np.ndarray | None = None
    frame: str = "world"


@dataclass(frozen=True)
class References:
    """What the active subtask asks of the HTMPC: the tasks' references and their priority order.

    `order` lists task names ('base', 'ee', 'posture') from highest priority; a name whose reference is None is
    skipped. `switched` is True on the first step after a subtask change (more SQP iterations). `posture`: the
    six arm joints' reference (K×6 or 1×6, rad), what the arm holds while the base drives.
    """

    order: tuple[str, ...]
    base: BaseReference | None = None
    ee: EEReference | None = None
    switched: bool = False
    posture: np.ndarray | None = None


class PlanStatus(StrEnum):
    """Outcome of one controller step."""

    OK = "ok"
    SLACK = "ok_with_slack"
    FALLBACK = "fallback_previous_plan"
    STOPPING = "stopping"
    FAILED = "failed"


class PlanReason(StrEnum):
    """Why a plan is what it is, for programs (the problems log counts by it); `Plan.message` is the free text
    for people, and rewording it changes no count."""

    NONE = "none"
    """A solved plan with nothing to report."""
    NO_TASK = "no_task"
    """Nothing to do (the sequence ended or has not started): holding, not a problem."""
    QP_FAILED = "qp_failed"
    """A level's QP failed: level 1 makes a braking plan, a later level keeps the earlier levels' plan."""
    SOLVE_TIMEOUT = "solve_timeout"
    """The step took longer than `HTMPCParams.solve_timeout_ms` (live runs only)."""
    NON_FINITE_STATE = "non_finite_state"
    CONTROLLER_ERROR = "controller_error"
    """The solve raised (any exception type)."""
    OUTSIDE_LIMITS = "outside_limits"
    """The solution broke the velocity or acceleration limits."""
    NO_ITERATION = "no_iteration"
    FAULT = "fault"
    """A loop of the runtime faulted: braking to rest."""


@dataclass(frozen=True)
class Plan:
    """One HTMPC solution: predicted q, v (N+1 × 9), u (N × 9), Cartesian paths and diagnostics."""

    t: float
    dt: float
    q: np.ndarray
    v: np.ndarray
    u: np.ndarray
    base_path: np.ndarray
    ee_path: np.ndarray
    task_errors: tuple[float, ...]
    solve_ms: tuple[float, ...]
    status: PlanStatus
    message: str = ""
    reason: PlanReason = PlanReason.NONE
    min_h: float = float("nan")
    extras: dict[str, float] = field(default_factory=dict)

    def velocity_at(self, t: float) -> np.ndarray:
        """Joint velocity the plan commands at time t (s): v_k + u_k (t − t_k), zero after the horizon.

        This is how the 100 Hz command stream is interpolated from the 10 Hz plan.
        """
        tau = t - self.t
        n = self.u.shape[0]
        if tau < 0.0:
            return self.v[0].copy()
        k = int(tau // self.dt)
        if k >= n:
            return np.zeros_like(self.v[0])
        return self.v[k] + self.u[k] * (tau - k * self.dt)


@dataclass(frozen=True)
class BackendAbilities:
    """What a robot backend can do beyond `observe` and `command`, declared by the backend itself
    (`RobotBackend.abilities`): the runtime asks, it never guesses from the backend's class (docs/design.md,
    "Writing a new backend"). The defaults are a real robot's: its own clock, no ground truth."""

    steps_in_lockstep: bool = False
    """Time advances only when the runtime calls `step(dt)` (`SteppableBackend`): lockstep runs, live physics
    paced by the run's speed, a pause that freezes the robot with its plan. False: the robot runs in real
    time, and a pause holds it still with zero commands."""
    simulated: bool = False
    """A simulation whose world the runtime may read and edit: scene edits, ground-truth distances and
    collisions, the ground-truth map (`core.sim.simulated_backend.SimulatedBackend`)."""
    camera_latency_s: float = 0.0
    """Time from a frame's exposure to its stamp (s), as far as the backend knows it (the simulated camera's
    exact offset); the map compensates it unless `MappingParams.camera_latency_s` is set (calibrated)."""


class RobotBackend(Protocol):
    """A robot the runtime drives: the MuJoCo simulation or a real robot behind the bridge."""

    @property
    def abilities(self) -> BackendAbilities:
        """What this backend can do beyond observe and command (`BackendAbilities`)."""
        ...

    def observe(self) -> Observation:
        """Latest joint state, odometry and the depth frames captured since the previous call."""
        ...

    def command(self, qdot: np.ndarray, t: float) -> None:
        """Joint velocity command qdot[9] (base x, y, yaw in the world frame; arm joints), stamped t."""
        ...


class SteppableBackend(RobotBackend, Protocol):
    """A backend whose time the runtime advances (`BackendAbilities.steps_in_lockstep`). Live, one thread
    steps it: `prepare_cameras()` before its first step makes what the cameras render with, unless it exists
    (a Reset's new thread renders with what the previous one made); `close()` frees it once no thread steps
    any more (either may do nothing)."""

    def step(self, dt: float) -> None:
        """Advance the robot's time by dt (s)."""
        ...

    def prepare_cameras(self) -> None:
        """Make what the cameras render with unless it exists, from the thread that will step (live, before
        its first step)."""
        ...

    def close(self) -> None:
        """Free it, once no thread steps any more (the runtime's shutdown)."""
        ...


def steps_in_lockstep(backend: RobotBackend) -> TypeGuard[SteppableBackend]:
    """Whether the runtime advances `backend`'s time (as it declares): then it has `step(dt)`."""
    return backend.abilities.steps_in_lockstep


class LocalizationStatus(StrEnum):
    """Who is in charge of the base pose estimate (`PoseEstimate.status`)."""

    ODOMETRY = "odometry"
    """Odometry alone: start-up, after Reset, or too little trusted surface in view so far."""
    LOCALIZED = "localized"
    """At least one registration against the map's trusted surfaces has been accepted."""
    LOST = "lost"
    """Registrations have disagreed with the estimate for `LocalizationParams.lost_after_s`: the base is held, the
    map paused, and a global search runs (`core/localization/lost.py`)."""


@dataclass(frozen=True)
class PoseEstimate:
    """The base pose the loop uses: pose (x, y, yaw) in the world frame, its covariance (3×3, m² and rad²)
    and who is in charge (docs/design.md, "State estimation")."""

    t: float
    pose: np.ndarray
    covariance: np.ndarray
    status: LocalizationStatus


@dataclass(frozen=True)
class ReferenceSurface:
    """What the map offers localization to register against: world points (P×3) of surfaces it trusts and
    the id of the mapped object each belongs to (-1: not an object, e.g. a voxel map's occupied cells).

    The map fills it (`core/mapping/reference_surface.py`); localization reads it and never the map itself."""

    t: float
    points: np.ndarray
    object_ids: np.ndarray
    merged_into: dict[int, int] = field(default_factory=dict)
    """Ids the map merged into one of these objects → that object: the same surface under an older id (a
    keyframe that labelled its points with the older id still shows a trusted surface)."""
