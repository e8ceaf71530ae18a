"""Tunables of the method, in one place, with the paper's names and units (docs/design.md, "Parameters").

Each component takes its own frozen parameter object; `dataclasses.replace` makes a variant.
Values follow docs/method.md, "Settings" (the HTMPC authors' configuration and POCD's reference values) unless a
docstring says why we differ.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field, fields
from functools import cache
from typing import Literal

import numpy as np

from core.types import Posterior

# The closed option sets of the tunables. Literals, not enums: the values stay plain strings in YAML and JSON,
# and a params file is checked against them by pydantic (`core/params_file.py`); `typing.get_args` lists them.
ConstraintKind = Literal["cbf", "edf"]
"""How the map's distance field bounds the robot: a CBF (eq. 10) or the plain h ≥ 0 baseline."""
Hierarchy = Literal["lexicographic", "weighted"]
"""How the task costs are ordered: strictly (eqs. 6–7) or as one weighted sum (for comparison)."""
SlackGroups = Literal["sphere", "body", "node"]
"""Collision slacks per node: one per sphere, one per body (base+rack, arm) or one per node."""
EDFGeometry = Literal["completed", "surface"]
"""What the object map's EDF measures the distance to: completed solid boxes, or observed surfaces (9a)."""
UnknownSpaceKind = Literal["obstacle", "free"]
"""Floor the cameras should have seen and got no depth from: an obstacle for the base, or free (the paper)."""
CameraName = Literal["base", "hand"]
"""The robot's two depth cameras."""


@cache
def _literal_fields(cls: type) -> tuple[tuple[str, tuple[str, ...]], ...]:
    hints = typing.get_type_hints(cls)
    return tuple((f.name, typing.get_args(hints[f.name])) for f in fields(cls)
                 if typing.get_origin(hints[f.name]) is Literal)


def check_choices(params: object) -> None:
    """Refuse a field outside its `Literal` option set: the one check of a closed option, made when the
    parameter object is built (files, the bridge and Python callers alike)."""
    for name, choices in _literal_fields(type(params)):
        value = getattr(params, name)
        if value not in choices:
            raise ValueError(f"{type(params).__name__}.{name} must be one of {choices}, got {value!r}")


@dataclass(frozen=True)
class RobotParams:
    """Geometry and limits of the UR10 on an omnidirectional (Ridgeback-like) base."""

    arm_mount_xyz_m: tuple[float, float, float] = (0.27, 0.0, 0.653)
    """Position of the UR10 `base_link` in the base frame (Ridgeback top plate plus riser)."""
    base_size_m: tuple[float, float, float] = (0.96, 0.79, 0.32)
    """Ridgeback footprint (length, width) and body height (the top of its body above the floor)."""
    base_clearance_m: float = 0.08
    """Height of the body's underside above the floor (wheels below it)."""
    rack_size_m: tuple[float, float, float] = (0.4, 0.5, 0.6)
    """The rack on the base's top plate behind the arm (length, width, height)."""
    rack_x_m: float = -0.25
    """Position of the rack's centre along the base's x axis."""
    base_speed_mps: float = 1.0
    base_yaw_rate_radps: float = 0.75
    arm_speed_radps: tuple[float, ...] = (2.16, 2.16, 3.15, 3.2, 3.2, 3.2)
    """UR10 joint speed limits from its URDF (2.16–3.2 rad/s)."""
    base_accel_mps2: float = 2.0
    base_yaw_accel_radps2: float = 2.0
    arm_accel_radps2: float = 4.0
    base_xy_limit_m: float = 50.0
    """Position bound on the base x and y (a large room; the MPC needs finite numbers)."""

    @property
    def footprint_radius_m(self) -> float:
        """Radius of the circle round the base's footprint: inside it the base fits at any yaw (0.62 m)."""
        return float(np.hypot(self.base_size_m[0] / 2, self.base_size_m[1] / 2))

    @property
    def v_max(self) -> np.ndarray:
        """Speed limit per joint, |v| ≤ v_max, units m/s or rad/s."""
        return np.array([self.base_speed_mps, self.base_speed_mps, self.base_yaw_rate_radps, *self.arm_speed_radps])

    @property
    def a_max(self) -> np.ndarray:
        """Acceleration limit per joint, |u| ≤ a_max."""
        base = [self.base_accel_mps2, self.base_accel_mps2, self.base_yaw_accel_radps2]
        return np.array(base + [self.arm_accel_radps2] * 6)


@dataclass(frozen=True)
class CameraParams:
    """A simulated depth camera (paper: hand camera range 3 m)."""

    width_px: int = 320
    height_px: int = 240
    fovy_deg: float = 58.0
    range_m: float = 3.0
    near_m: float = 0.1
    rate_hz: float = 10.0


@dataclass(frozen=True)
class SensorParams:
    """The sensor model: what makes the simulated robot perceive its world as a real one does.

    `SensorParams()` is on (the studio, the bridge's simulated driver and the experiments' perceived
    runs); `SensorParams.ideal()` is exact sensing (the ground-truth map, geometry tests). Each effect is
    measured on rendered frames in `tests/core/sim/test_sensor_model.py`. Defaults are those of a
    stereo depth camera (RealSense D435-like) and the wheel odometry of an omnidirectional base.
    """

    depth_noise_m: float = 0.005
    """Depth std at 1 m; std = depth_noise_m · z² (stereo: σ_z = z² σ_disparity / (f b); the D435 at
    f = 380 px, b = 5 cm, 0.08 px subpixel gives 0.0042)."""
    dropout_fraction: float = 0.02
    """Pixels that return nothing at random (speckle on low-texture patches)."""
    flying_pixel_fraction: float = 0.5
    """Pixels next to a depth edge that read a depth between the two sides (mixed pixels)."""
    flying_pixel_jump_m: float = 0.1
    """A depth step larger than this between neighbouring pixels is an edge."""
    odometry_drift_m: float = 0.01
    """Random walk of the base position estimate: std per axis after 1 m driven grows as √distance (m/√m)."""
    odometry_drift_rad: float = 0.01
    """Random walk of the heading estimate: std after 1 rad turned grows as √angle (rad/√rad)."""
    camera_time_offset_s: float = 0.02
    """A frame is stamped this long after it was taken: its pose is the robot's estimate at the stamp, and
    it arrives then (the map compensates it: `MappingParams.camera_latency_s`)."""
    slip_at_s: float | None = None
    """A one-off odometry error (a wheel slip, a kidnap) at this robot time (s; None: never): the pose the robot
    reports jumps by `slip_m` and `slip_rad` while the true robot does not move (`odometry_drift.py`). A teleport
    (`SimWorld.set_robot`) is no slip: it restarts odometry at the true pose."""
    slip_m: tuple[float, float] = (0.0, 0.0)
    """The slip's position error (m) along the base's x (forward) and y (left) at the slip."""
    slip_rad: float = 0.0
    """The slip's heading error (rad), about the base's centre."""

    @classmethod
    def ideal(cls) -> SensorParams:
        """Exact depth and odometry, frames stamped when taken."""
        return cls(depth_noise_m=0.0, dropout_fraction=0.0, flying_pixel_fraction=0.0, odometry_drift_m=0.0,
                   odometry_drift_rad=0.0, camera_time_offset_s=0.0)


@dataclass(frozen=True)
class SimParams:
    """The MuJoCo world."""

    timestep_s: float = 0.002
    """500 Hz physics (paper: commands at 100 Hz)."""
    walls: bool = False
    room_half_size_m: float = 6.0
    floor_beyond_room_m: float = 10.0
    """Without walls the floor reaches this far past the room (m), beyond every camera's range: a floor that
    ended in view would read as no return, which the unknown-space rule rightly treats as not free."""
    hand_camera: CameraParams = field(default_factory=CameraParams)
    base_camera: CameraParams = field(default_factory=CameraParams)
    sensor: SensorParams = field(default_factory=SensorParams)
    """The sensor model of the simulated robot (`SimRobot`); on by default, a simulated robot is a real one."""
    box_pool: int = 32
    """Boxes pre-allocated as hidden mocap bodies; adding beyond the pool recompiles (grows it ×2)."""
    distance_margin_m: float = 2.0
    """Robot–box distances beyond this are reported as this value (saves narrow-phase work)."""


@dataclass(frozen=True)
class HTMPCParams:
    """Lexicographic MPC and CBF (docs/method.md, "Settings": the HTMPC authors' configuration)."""

    N: int = 10
    dt_s: float = 0.3
    gamma: float = 1.0
    """CBF decay rate: dh/dt ≥ −gamma h. Smaller is more cautious."""
    delta_safe_m: float = 0.25
    constraint: ConstraintKind = "cbf"
    """'cbf' (eq. 10) or 'edf' (h ≥ 0 baseline)."""
    lex_tolerance: float = 0.01
    """Added to the stored |e_i*| in (7c), nodes 2..N (m or rad)."""
    lex_tolerance_first_node: float = 1e-4
    """The same at node 1, the part of the plan the robot executes: there a tolerance is spent again at every
    control step and level 1 settles tol / (1 − ρ) off its optimum (`level_problem.lex_tolerances`)."""
    box_iterations: int = 2
    """Alternating projections per solve that find the base boxes' points closest to the obstacles
    (`box_barrier.py`). More iterations bring the points closer to the true closest ones at proportionally
    more work; 2 is where the error became negligible (docs/decisions.md, "Exact barriers for the base's
    boxes")."""
    slack_linear: float = 50.0
    slack_quadratic: float = 1.0
    slack_groups: SlackGroups = "body"
    """Collision slacks per node: 'sphere' (one per sphere), 'body' (base+rack, arm) or 'node' (one).
    Fewer slacks make each QP stage smaller (HPIPM's cost grows with the cube of its size)."""
    Q_base: tuple[float, float, float] = (1.0, 1.0, 0.5)
    Q_ee: tuple[float, float, float, float, float, float] = (1.0, 1.0, 1.0, 0.2, 0.2, 0.2)
    Q_posture: tuple[float, float, float, float, float, float] = (0.5, 0.5, 0.5, 0.5, 0.5, 0.5)
    """Weights of the arm posture task (per rad of the six arm joints), what the arm holds while the base drives."""
    Q_edot: float = 0.01
    Q_x: float = 1e-3
    Q_u: float = 1e-2
    sqp_iters: int = 1
    """Real-time iteration: one QP per level per control step."""
    sqp_iters_on_switch: int = 5
    """More Gauss-Newton iterations right after a subtask switch (the warm start is far off then)."""
    sqp_switch_carry: int = 0
    """Further iterations of a switch, spent on the following steps, at most `sqp_iters_on_switch` a step (until
    the plan stops moving). Measured with `sqp_iters_on_switch` 2 and this 3 (2 + 2 + 1 over three steps): the
    first step's longest 18 ms against 57 ms at load 5, the same tasks done (docs/decisions.md, "A task's first
    step spread over three"); off by default until E1–E4 are re-run with it (every lockstep run changes)."""
    sqp_step_tol: float = 1e-3
    """Those iterations stop early once no joint of the plan moved more than this (m or rad) in one."""
    sqp_damping: float = 1e-3
    """Levenberg-Marquardt term ½ λ ‖q_k − q̄_k‖² per node in a real-time iteration (one QP per level from
    the shifted previous plan). Smaller values follow the nonlinear optimum more closely but let a plan
    overshoot the linearised collision rows; larger ones slow convergence (docs/decisions.md, "Damping of the
    real-time iteration"). It vanishes at convergence (q = q̄)."""
    sqp_damping_on_switch: float = 1e-2
    """λ when iterating after a switch. Gauss-Newton drops the curvature of the task errors (large while
    the EE is far from its goal), and in the directions only the small J_aux weights hold, iterations
    cycled with large steps unless damped this much (docs/decisions.md, "Damping of the real-time
    iteration")."""
    control_rate_hz: float = 10.0
    """The control step's rate when nothing new is seen (its period is also the instant the step rows hold at)."""
    command_rate_hz: float = 100.0
    control_on_new_map: bool = True
    """Also run a control step as soon as the map has taken a new frame of `control_trigger_cameras`, and start
    the control period from it: a newly seen obstacle reaches the plan without waiting for the next period
    (our addition; docs/decisions.md, "Control on a new map")."""
    control_trigger_cameras: tuple[str, ...] = ("base", "hand")
    """Whose integrated frames trigger a control step (`control_on_new_map`)."""
    control_max_rate_hz: float = 20.0
    """A camera's frames trigger steps no closer than 1 / this (s of robot time) apart: bounds the CPU a fast
    camera costs (the two 10 Hz cameras trigger at most 20 steps a second together)."""
    hierarchy: Hierarchy = "lexicographic"
    """'lexicographic' (eqs. 6–7) or 'weighted' (one weighted-sum MPC, for comparison)."""
    trust_region_m: float = 1.0
    """Per SQP iteration, base x and y may move at most this far from the linearisation point ..."""
    trust_region_rad: float = 0.5
    """... and the yaw and arm joints at most this much: Gauss-Newton steps on the nonlinear FK and the
    linearised EDF stay where their models hold (full steps from a far warm start diverge)."""
    solve_timeout_ms: float = 250.0
    """A step slower than this is discarded: the robot brakes on the shifted previous plan."""

    def __post_init__(self) -> None:
        check_choices(self)


@dataclass(frozen=True)
class MappingParams:
    """Object-level map (POCD), the voxel-level baseline map and the local EDF (core/mapping).

    POCD's reference values (docs/method.md, "Settings") unless a docstring says why we differ; the removal-speed
    choice (cap, forced-outlier weight) is argued in `core/mapping/object_mapper.py`, with its figures in
    docs/decisions.md ("Removal speed").
    """

    # --- depth → points --------------------------------------------------------------------------
    voxel_m: float = 0.05
    """Object submap resolution and segmentation voxel (POCD: 5 cm)."""
    range_m: float = 3.0
    """Depth beyond this is ignored (paper: hand camera range 3 m)."""
    pixel_stride: int = 2
    """Use every n-th pixel in u and v (at 3 m, 2 px ≈ 2.8 cm < one 5 cm voxel)."""
    floor_height_m: float = 0.03
    """Points below this height are the floor."""
    flying_pixel_jump_m: float = 0.1
    flying_pixel_jump_per_m: float = 0.05
    """A pixel whose 3 × 3 neighbourhood spans more depth than jump + jump_per_m · z (+ 6 noise std) is a
    flying pixel at a depth edge and is not used (`core/mapping/flying_pixels.py`)."""
    flying_pixel_min_support: int = 3
    """... and so is a pixel beside a silent one and behind a nearer one with fewer of its 8 neighbours on its
    surface (within 3√2 noise std + `flying_pixel_support_slope` · z): a mixed pixel against a background beyond
    the range, which the span test cannot see. A box's corner pixel has 3. 0 switches the test off."""
    flying_pixel_support_slope: float = 0.03
    """Depth step (m per m of depth) between neighbouring pixels of one surface at a grazing angle: up to
    ~82° from its normal at the cameras' 4.2 mrad pixels (0.01, 67°, dropped an aisle wall's far grazing
    stretch near the range and read the EDF 5.6 cm beyond the truth in `test_map_driving.py`)."""
    floor_snap_m: float = 0.15
    """An object's fitted box whose lowest surface point is within this height of the floor is extended down
    to it (the floor filter cuts a box's bottom few centimetres). Lower parts hidden from view are completed
    by the solid box instead (`assumed_depth_m`), which stops where free space was seen under the object: a
    box at hand height stays floating (a snap of 10 m made it a floor-to-top column)."""
    assumed_depth_m: float = 0.6
    """Box completion (`core/mapping/completion.py`): an object seen from one side only, thinner than this,
    is solid this deep behind the faces seen, until free space is seen there (the paper's boxes: 0.6 m)."""
    self_filter_margin_m: float = 0.0
    """Points within the robot's collision spheres grown by this margin are the robot itself."""
    camera_latency_s: float | None = None
    """Calibrated time from a frame's exposure to its stamp: the map places each frame at the camera pose
    of its exposure (`core/mapping/frame_exposure.py`). None: the latency the robot backend declares
    (`BackendAbilities.camera_latency_s`): the simulated camera's own offset (`SensorParams.camera_time_offset_s`,
    an exact calibration), 0 with a real robot (set it there)."""

    # --- segmentation, association, registration ---------------------------------------------------
    min_segment_voxels: int = 8
    """Smaller clusters of occupied voxels are noise, not objects."""
    cost_sample_points: int = 128
    """Association costs, the registration trigger and Delta are means over at most this many of a
    segment's voxels (an even sample; all voxels are fused into the submap)."""
    association_cap_m: float = 0.5
    """Per-point distances to an object's surface are truncated here before averaging (the cost)."""
    association_gate_m: float = 0.25
    """A segment matches an object when its truncated mean distance to the surface is below this."""
    explain_m: float = 0.1
    """A point within this of an object's surface is explained by it (association cost, sharing a segment
    among touching objects)."""
    split_fraction: float = 0.1
    """An object explaining at least this fraction of a segment gets its share of the segment's points."""
    duplicate_fraction: float = 0.5
    """An object whose explained points are at least this fraction explained by a larger one is merged into it."""
    box_fill_max_m: float = 0.75
    """An object is box-like (solid box in the EDF) when its box's footprint is everywhere within this of
    the seen surface (`core/mapping/footprint.py`); a box seen from two sides qualifies, walls around a
    corridor do not."""
    hollow_min_through: int = 3
    """A box-like object whose box interior (samples at `edf_voxel_m`, `explain_m` in from its faces) is seen
    through at this many samples in one check is hollow: mapped by its surface from then on."""
    registration_max_extent_m: float = 1.6
    """Only box-like objects with a footprint no longer than this are registered (pushable things)."""
    merge_gate_m: float = 0.08
    """A second segment lying on an already matched object's surface (mean distance below this) joins it."""
    registration_trigger_m: float = 0.04
    """ICP runs when at least `registration_trigger_fraction` of a matched segment's sample lies farther than
    this (m) from its object's surface."""
    registration_trigger_fraction: float = 0.2
    registration_accept_ratio: float = 0.7
    """ICP's motion is taken only when it brings the sample's mean distance below this fraction of what it was
    before ..."""
    registration_min_gain_voxels: float = 0.5
    """... and closer by more than this many voxels (× `voxel_m`): a shift within the voxel noise is no push;
    and only when it explains the segment (less than `registration_trigger_fraction` of the sample left farther
    than `registration_trigger_m`): a row of alike boxes half-explained by sliding one along it is no push."""
    icp_max_correspondence_m: float = 0.35
    icp_max_iterations: int = 30
    icp_normal_neighbours: int = 16
    """Neighbours of each submap point in the point-to-plane ICP's normal estimate (about a 2.5-voxel disc of
    a voxel-grid surface)."""

    # --- POCD consistency (eqs. 1–4) --------------------------------------------------------------
    tau_m: float = 0.2
    """Inlier std tau of Delta (POCD: 0.2 m)."""
    delta_max_m: float = 4.0
    """Outlier support: Delta ~ U(−Delta_max, Delta_max) (POCD: 4 m)."""
    theta_stat: float = 0.4
    """Remove an object when E[v] < theta_stat after more than `min_observations` updates."""
    min_observations: int = 2
    alpha0: float = 2.0
    beta0: float = 1.0
    mu0_m: float = 0.0
    sigma0_m: float = 0.5
    beta_cap: float = 10.0
    """Cap on alpha and beta (both rescaled, ratio kept, when the larger exceeds it). POCD: 25; we use
    10 so the belief remembers about one second of frames and a moved box goes fast."""
    forced_outlier_weight: float = 3.0
    """w_max: a forced outlier adds up to this to beta, scaled by the clear-view evidence (POCD: 1)."""
    weight_by_clear_view: bool = True
    """Scale the forced outlier by the clear-view evidence; False adds `forced_outlier_weight` flat (POCD
    with weight 1)."""
    clear_view_fraction: float = 0.5
    """A missing object is a forced outlier only if at least this fraction of its expected-visible
    surface had free space seen through it."""
    clear_view_voxels: int = 30
    """Seen-through surface voxels at which the forced-outlier weight saturates at w_max."""
    min_expected_voxels: int = 6
    """Fewer expected-visible surface voxels than this is no evidence at all."""
    visibility_margin_m: float = 0.1
    """A surface point is 'hit' when the measured depth is within this (plus noise) of its depth."""
    through_patch_px: int = 2
    """A surface point is 'seen through' only if every pixel within this many of its own reads beyond it
    (surfaces at grazing angles; `core/mapping/visibility.py`)."""
    depth_noise_coeff_m: float = 0.005
    """Sensor model for the margins: depth std = coeff · z² (stereo-like); 3 std are added to margins."""
    semantic_weight_k: float = 0.0
    """k on the semantic term (eq. 3). 0: with s = 0 every frame, k ≥ 1 drifts still boxes to removal."""
    semantic_static_s: float = 0.0
    """s for every object (all boxes here are 'likely to move')."""
    carve_after_misses: int = 3
    """A submap voxel seen through in this many carving checks since it was last hit is carved away."""
    carve_check_every: int = 3
    """A matched object's surface is checked for seen-through voxels every this many of its observations by each
    camera (a projection of the whole submap: carving is slow evidence, no need to pay for it every frame). The
    completion samples are checked then too; a sample seen through in `carve_after_misses` checks is free."""

    # --- voxel-level baseline (OctoMap-style log-odds, projective free-space carving) -------------
    logodds_hit: float = 0.85
    logodds_miss: float = -0.4
    logodds_min: float = -2.0
    logodds_max: float = 3.5
    """OctoMap's defaults (hit 0.7, miss 0.4, clamping 0.12–0.97); occupied when log-odds > 0."""

    # --- local EDF (9a–9b) --------------------------------------------------------------------------
    edf_geometry: EDFGeometry = "completed"
    """What the object map's EDF is the distance to: 'completed' (box-like objects are their solid boxes,
    `core/mapping/completion.py`; the others their surface columns) or 'surface' (the paper's 9a: the
    objects' observed surface voxels only, so unseen sides and insides read as free)."""
    edf_window_m: tuple[float, float, float] = (4.0, 4.0, 1.4)
    """Grid around the robot (x, y, z from the floor up)."""
    edf_voxel_m: float = 0.1
    """EDF grid spacing (the authors used 0.2 m)."""
    theta_cutoff_m: float = 1.8
    """Distances are truncated here; outside the window the field is this constant."""
    surface_shell_ratio: float = 40.0
    """An object mapped by its surface (not box-like) enters the EDF without the points whose EDF cell weighs
    (depth-noise weights) less than 1/this of a neighbour cell: the noise shell in front of a face seen from
    afar (`core/mapping/noise_shell.py`); 0 keeps every point."""
    theta_zero_m: float = 0.05
    """Submap voxels with |M_i| ≤ theta_zero are the object's surface (9a). Here by construction: a submap
    keeps only the voxels surface points fell in, whose centroids are at |M_i| = 0 (`submap.py`); this is
    the paper's symbol, not a knob."""

    # --- unknown space (our addition to the paper: core/mapping/unknown_floor.py) --------------------------
    unknown_space: UnknownSpaceKind = "obstacle"
    """'obstacle' (our addition): floor cells that rays should have met within `unknown_floor_range_m` and that
    returned no depth are columns in the EDF (so the CBF slows and stops the base before them) and in the
    planner's occupancy. 'free': the paper's map, where no return is no evidence for driving either."""
    unknown_cameras: tuple[str, ...] = ("base",)
    """The cameras whose frames give the evidence. Not the hand camera: passing close to boxes, its rays are cut
    short by its near clip (0.1 m), and on the aisle's first lap it marked 850 cells where nothing was dark
    (the base camera 3; docs/decisions.md, "Unknown space as an obstacle")."""
    unknown_floor_range_m: float = 2.5
    """Only rays whose floor point lies within this depth count (below the 3 m range, so that noise never
    pushes a floor return out of range)."""
    unknown_floor_min_depth_m: float = 0.3
    """... and beyond this depth (a camera's near clip, 0.1 m, also reads 0: a hand close to the floor)."""
    unknown_cell_m: float = 0.1
    """Floor cells of the evidence (m)."""
    unknown_evidence_rays: int = 5
    """A cell turns unknown when its aimed rays that returned nothing outnumber those that returned something by
    this many, summed over frames (`unknown_floor.py`); floor seen there takes it back. A dark box's shadow gets
    there in one frame (every ray misses); the 2 % random dropouts, at 5 rays a cell at 2.5 m, once an hour in
    the camera's 4,000 cells a frame at 10 Hz (3 in one frame, the earlier rule: 2 a minute)."""
    unknown_evidence_max_rays: int = 10
    """The evidence is clipped at this many rays, so that floor seen again clears a cell within a frame or two."""
    unknown_height_m: float = 1.0
    """Height of an unknown column (m): above the base's rack (0.92 m), so no part of the base passes over."""

    def prior(self) -> Posterior:
        """The belief q(l, v) a new object starts with: N(mu0, sigma0²) · Beta(alpha0, beta0)."""
        return Posterior(mu=self.mu0_m, sigma=self.sigma0_m, alpha=self.alpha0, beta=self.beta0)

    def __post_init__(self) -> None:
        check_choices(self)


@dataclass(frozen=True)
class SequencerParams:
    """Turning the active subtask into HTMPC references (tasks/), and base path planning."""

    nominal_speed_mps: float = 0.6
    """Speed at which base references advance along the planned path."""
    lookahead_m: float = 1.5
    """In navigation the hand camera looks at the path point this far ahead."""
    lookahead_turn_max_deg: float = 60.0
    """The most the arm turns at the shoulder (from its ready pose) to look ahead along the path."""
    plan_bounds_m: tuple[float, float, float, float] = (-8.0, 8.0, -8.0, 8.0)
    """The A* grid's extent in the world: x_min, x_max, y_min, y_max."""
    grid_cell_m: float = 0.1
    inflation_m: float = 0.8
    """Obstacles are grown by this radius for A*: about the clearance the controller keeps (the base's half
    length 0.48 m + delta_safe 0.25 m, and a grid cell), so planned paths are ones it follows without pressing
    on its constraints. The experiments that compare constraints plan with the footprint alone
    (`RobotParams.footprint_radius_m`) and leave the clearance to the constraint: with 0.8 m planned paths
    kept h ≈ 0 and the CBF and the EDF constraint rarely differed (E2). (With 0.62 m in E1 the robot drove
    close enough to the vacated places to clear the voxel map's phantoms: a different experiment.)"""
    inflation_min_m: float = 0.65
    """Where `inflation_m` leaves no path (or skips a waypoint), A* plans again with this: the base's half
    width 0.395 m + delta_safe 0.25 m, the narrowest passage it drives through lengthwise with delta_safe on
    both sides (a 1.9 m aisle keeps 0.6 m of planning width instead of 0.3 m, room for a map or a pose estimate
    some 10 cm off). The operator is told ("a narrow passage")."""
    obstacle_z_m: tuple[float, float] = (0.05, 2.0)
    """Occupied points between these heights block the base."""
    stance_turn_deg: float = 20.0
    """An EE subtask whose base starts farther than this (deg) from its stance's heading (the stance faces the
    target) turns the base into its stance first, the arm at its ready joints, until within it, then takes its own
    order (`tasks/stance_turn.py`): side-on, the base stops at delta_safe beside what lies under the target and the
    arm reaches at full stretch. `math.inf`: never (the hand's task first from the start)."""
    replan_period_s: float = 1.0
    waypoint_pass_m: float = 0.5
    """An intermediate base waypoint counts as passed once the base is this close to it (or beyond the
    plan's nearest point to it); re-plans then start from the next one."""
    goal_slowdown_m: float = 0.8
    """Within this distance of the final goal the reference stops advancing past it."""
    stall_s: float = 10.0
    """A base subtask whose distance to go along its planned path (through the waypoints ahead; the
    straight-line error without a plan) has not fallen by `stall_progress_m` for this long (s, subtask time)
    says "blocked" with the nearest obstacle (the run goes on until its timeout or a Skip)."""
    stall_progress_m: float = 0.1
    anchor_follow_m: float = 0.1
    """An anchored target that moved more than this since the plan was made (the map found its object
    elsewhere) re-makes the plan and the A* path, and the operator is told; below it the references follow
    the object every period without a re-plan (the map's pose jitters by a few centimetres)."""
    anchor_bind_radius_m: float = 0.45
    """A name whose object is not bound yet binds to the mapped object whose centre is nearest to where the
    name was given (or, in simulation, where the named scene box is), if within this radius (3/4 of a box)."""
    anchor_candidate_margin_s: float = 1.0
    """A lost name re-binds only to an object first mapped at most this long before its own object was last
    observed (a box moved far is a new object, seen before the old one is removed)."""
    anchor_settle_m: float = 0.15
    """An anchored subtask does not complete (its dwell does not count) while its object, of known size, is mapped
    longer than that size by more than this along a horizontal axis: the map has fused the box's old and new
    places after a move (seen: 1.02 m for a 0.6 m box pushed 0.5 m). 2 × a pick's 3 cm tolerance held a lap-1
    pick 0.7 cm from the true box on a 0.67 m box (bench)."""
    anchor_base_settle_s: float = 5.0
    """A base subtask held this long (s) at its goal on an unsettled object completes on the map's box as it is: from
    the goal no camera may see a moved box's old place, which then stays fused (the anchored-picks bench: 4 of 10
    runs stood 35 s at the approach until its timeout). A hand target keeps waiting: its camera sees the box from
    above."""
    anchor_overlap_margin_m: float = 0.15
    """... or to one that stands where the lost object stood: the two footprints, at the box's known size, overlap
    by more than this (m) along every side (two boxes side by side touch, mapped within a few centimetres)."""


@dataclass(frozen=True)
class LocalizationParams:
    """Change-aware localization of the base (core/localization; docs/method.md, "State estimation").

    Odometry predicts, scan-to-map registration of the base camera's frames against the map's trusted surfaces
    corrects, every correction gated; starting values from docs/decisions.md ("Localization")."""

    enabled: bool = False
    """Off in the library's defaults, which the experiments and benchmarks were measured with; the app starts
    with it on (`app/launch_defaults.py`; docs/decisions.md, "Localization on when the app starts")."""
    camera: CameraName = "base"
    """Whose frames are registered (the base camera sees the floor and the boxes around the base)."""
    rate_hz: float = 5.0
    """Registrations per second of robot time (frames in between are skipped). 5 Hz did better than 2 Hz on E4's
    lap 1 (docs/decisions.md, "Localization"): turns are followed while what was seen before is still in view."""
    processing_s: float = 0.05
    """Lockstep: a correction applies at its frame's stamp plus this modelled processing time."""
    drift_m_per_sqrt_m: float = 0.01
    """Process noise of the odometry prediction: position std per axis after 1 m driven (m/√m)."""
    drift_rad_per_sqrt_rad: float = 0.01
    """Process noise of the odometry prediction: heading std after 1 rad turned (rad/√rad)."""
    initial_sigma_m: float = 0.001
    initial_sigma_rad: float = 0.001
    """The start pose defines the world frame: it is known up to these."""
    stride_px: int = 2
    """Every stride-th pixel of a frame, each way, is registered."""
    source_voxel_m: float = 0.05
    """The frame's points are thinned to one a voxel of this size before registration."""
    max_range_m: float = 3.0
    """Depths beyond this (m) are left out (noise grows as z²)."""
    reference_crop_m: float = 4.5
    """Reference points farther than this (m, in x-y) from the predicted base are left out."""
    floor_step_m: float = 0.1
    """The floor z = 0 enters the reference as a grid of this pitch (m) around the predicted base."""
    radius_sigmas: float = 3.0
    radius_margin_m: float = 0.05
    radius_min_m: float = 0.1
    radius_max_m: float = 0.5
    """Correspondence radius clip(radius_sigmas σ + radius_margin_m, radius_min_m, radius_max_m): tied to the
    pose's current uncertainty σ, so a box moved farther than that finds no partner and cannot drag the pose."""
    max_iterations: int = 20
    min_source_points: int = 300
    """A frame with fewer points after thinning is not registered (counted as a failure)."""
    min_inlier_share: float = 0.5
    """Gate: the share of the frame's points with a partner within the radius."""
    chi2_gate: tuple[float, float, float] = (6.63, 9.21, 11.34)
    """Gate: χ² of the innovation against the prediction, 1 % tail for 1, 2, 3 constrained directions."""
    degenerate_information: float = 2.0
    """A direction whose information per inlier (Schur complement of the registration's H on x, y, yaw; yaw
    weighed by the points' RMS distance from the base) is below this gets no correction: the floor alone reads
    ~0.5 along every direction of the floor, a single wall ~0.5 along itself and ≥ 100 across."""
    sigma_xy_m: float = 0.03
    sigma_yaw_rad: float = 0.01
    """Measurement std of a well-constrained direction (never H⁻¹ as it is: it claims cm along directions
    nothing constrains); a direction with information λ < 5 × `degenerate_information` is inflated by
    λ ↦ 5 × degenerate_information / λ in variance. Against the self-built map 3 cm / 0.57° did better than
    1 cm / 0.17° on E4's lap 1 (docs/decisions.md, "Localization")."""
    min_trusted_points: int = 150
    """Odometry stays alone in charge until this many trusted object surface points (5 cm apart: ~0.4 m² of
    surface) lie within the camera's range of the predicted base."""
    trust_consistency: float = 0.7
    """An object enters the reference when its E[v] is at least this…"""
    trust_observations: int = 5
    """…and it has been seen at least this many times."""
    disagreement_m: float = 0.04
    """After registration, an object whose frame points sit farther than this (median, m) from its reference
    surface disagrees: it leaves the reference (registration runs again without it) and is reported to the
    map as change evidence."""
    disagreement_from_planes: bool = True
    """Judge that distance from the side faces' planes (`Target.side_offsets`), and an object the predicted frame looks
    through beyond the correspondence radius as off (`see_through_share`); off: from the nearest reference sample, the
    judge before 2026-11-29, which read a far face seen obliquely as moved (docs/decisions.md, "A new row read as
    moved")."""
    min_object_points: int = 20
    """An object's disagreement is judged on at least this many of the frame's points near it."""
    see_through_share: float = 0.5
    """With `disagreement_from_planes`: an object whose reference points in view (and not hidden) the frame, at its
    predicted pose, looks through by more than the correspondence radius, at least this share of them, disagrees by
    the median depth it is looked through (`core/localization/see_through.py`): a slip toward a wall places the wall's
    points at the gate, where no residual judges them."""
    exclusion_s: float = 10.0
    """A disagreeing object stays out of the reference this long (s): the map meanwhile re-places or removes it."""
    agreed_recently_s: float = 1.0
    """An object that fitted an accepted registration within this long (s of robot time) and now pulls a refused one
    has moved: the pose cannot have jumped that far since without a slip (docs/decisions.md, "A moved box pulled a
    right pose")."""
    freeze_reference: bool = False
    """Register against each trusted object's surface where it was when first trusted
    (`core/localization/frozen_surfaces.py`), not where the map has it now (the map re-places objects onto frames
    posed by a drifting estimate, so its surfaces follow the drift). Off by default: on E4's aisle it did better
    on lap 1 for two seeds of three but worse on lap 2 for both seeds measured (it keeps what was frozen while the
    pose had drifted; docs/decisions.md, "Localization")."""
    freeze_sigma_m: float = 0.1
    """An object's surface is frozen (or grows) only while the pose's std (x-y, plus the heading's at half the
    range) is at most this (m): not after a long stretch of odometry alone. On E4's lap 1 the std stayed under
    6 cm, so this never held a surface back there."""
    freeze_grow_m: float = 0.1
    """A frozen surface grows by the map's points farther than this (m) from it (newly seen parts)."""
    refreeze_disagreeing: bool = True
    """An object found disagreeing is dropped from the frozen reference and frozen again from the map later."""
    reference_period_s: float = 2.0
    """The loop asks the map for its trusted surfaces at most this often (s); the prepared reference is kept
    while the surfaces and the base's 1 m cell stay the same."""
    untrusted_after_s: float = 10.0
    """Health (`core/localization/health.py`): no correction accepted for longer than this (s of robot time, counted
    from the start while none has been) makes the pose untrusted, a problem the operator sees."""
    trust_sigmas: float = 3.0
    trust_delta_share: float = 0.5
    """Health: the pose is untrusted while trust_sigmas σ_xy (σ_xy the largest position std of P, m) exceeds
    trust_delta_share × delta_safe (`HTMPCParams.delta_safe_m`): the position may be off by more than the margin
    can spare."""
    grow_margin: bool = True
    """Our addition (docs/method.md, "State estimation"): the controller's delta_safe grows by what the pose's
    uncertainty eats of it, clip(trust_sigmas σ_xy − trust_delta_share delta_safe, 0, margin_growth_max_m); zero
    while the pose is trusted by its σ. False: delta_safe as configured, whatever the uncertainty."""
    margin_growth_max_m: float = 0.3
    """The most the margin grows (m): beyond it the robot would not pass anything at all."""
    lost_after_s: float = 0.5
    """Lost (`core/localization/lost.py`): registrations that had trusted surface in view and were refused by a gate
    (χ², inconsistent, few inliers) one after another for at least this long (s of robot time, first to last refused
    frame; no accepted one and none with nothing to register against between; degenerate and not converged ones
    neither break nor extend the streak)…"""
    lost_jump_m: float = 0.25
    lost_jump_rad: float = 0.17
    """A χ² refusal counts towards lost only if its innovation along the constrained directions is at least this
    (m in x-y, or rad, ~10°): a smaller one says the filter was too sure of itself (with a self-built reference its σ
    runs below the drift), and P grows by the innovation instead. A slip of the issue's size (0.5 m, 30°) is larger."""
    lost_min_refusals: int = 3
    """…and at least this many of them make the localizer LOST: the base stops, mapping pauses and a global search
    runs. From the first such refusal frames wait (are not integrated) until a registration passes again."""
    hold_frames: bool = True
    """Frames wait for the verdict of the next registration at or after their exposure before the map integrates
    them (at most 1 / `rate_hz` later), so that frames at a pose that has jumped (a slip) are never integrated:
    dropped when the localizer gets lost. Not while the latest registration had no trusted surface in view (no
    verdict could refuse them). False: frames are integrated as they come (a slip's first frames go in)."""
    hold_max_s: float = 1.0
    """A frame waits at most this long (s of robot time past its exposure) for a verdict while nothing is refused
    (no base-camera registration came): then it is integrated."""
    search_xy_m: float = 1.0
    search_step_m: float = 0.25
    """Global search: initial guesses on a grid of this pitch (m) within ±search_xy_m of the estimate, along the
    base's x and y…"""
    search_yaw_rad: float = math.radians(30.0)
    search_yaw_step_rad: float = math.radians(10.0)
    """…and in heading within ±search_yaw_rad (rad) at this pitch (rad): 9 × 9 × 7 guesses by default."""
    search_coarse_m: float = 0.25
    """A guess is scored, before any registration, by the share of the frame's points above the floor that lie
    within this distance (m) of the reference's object surfaces (the floor fits every guess; it is not scored)."""
    search_refined: int = 12
    """The best-scored guesses registered by GICP (within `radius_max_m`) against the floor and the surfaces."""
    search_inlier_m: float = 0.05
    """A registered guess's score: the share of the frame's points above the floor within this distance (m) of an
    object surface."""
    search_min_score: float = 0.8
    """The best registered guess is accepted only with at least this score… (the slips of
    `tests/app/test_localization_slip.py` were found at 0.98–0.99; on E4's aisle a false alarm's best guess, 1.2 m
    off, scored 0.61)"""
    search_margin: float = 0.15
    """…and only if it is unique: every registered guess ending at a distinct pose (farther than `search_distinct_m`
    or `search_distinct_rad` from the best) scores at least this much less (shares; a uniform wall, where every
    guess along it fits alike, is not unique). Before any of that: if the estimate itself (no offset) scores within
    this of the best guess before registration, nothing jumped beyond `search_coarse_m` and the run goes on from
    the estimate."""
    search_distinct_m: float = 0.15
    search_distinct_rad: float = math.radians(5.0)
    """Two registered guesses are the same pose within these (m, rad)."""
    search_tries: int = 5
    """Searches (one a frame, each on a new frame once the last one's modelled time has passed) before the run
    faults with "lost localization"."""
    search_processing_s: float = 0.5
    """Lockstep: a search's outcome (re-anchoring or a failed try) comes at its frame's stamp plus this modelled
    time (a search is slower than one registration)."""
    search_sigma_m: float = 0.05
    search_sigma_rad: float = 0.02
    """After re-anchoring, the covariance P restarts at these stds (m, rad): what one registration from a far guess
    is good to."""
    loop_closure: bool = True
    """A pose graph of keyframes closed onto the places an earlier visit kept (`core/localization/loop_closure.py`;
    docs/method.md, "State estimation", "Loop closure"): where an earlier visit's keyframe is near, frames register
    against those keyframes (placed by the optimised graph) instead of the map's surfaces, and T_world←odom follows
    the optimised graph. On by default within localization (which itself is off by default): on E4's three aisle laps
    (seeds 0 / 1 / 2, same code) ATE RMSE 7.2 / 6.2 / 6.0 cm against the filter alone's 20.7 / 6.9 / 8.7 cm, lap 3
    4.2 / 6.2 / 4.8 cm against 28.7 / 6.8 / 11.1 cm, 45 / 45 subtasks against 44 (docs/decisions.md, "Localization",
    issue 25 fifth round)."""
    keyframe_step_m: float = 0.3
    keyframe_step_rad: float = math.radians(15.0)
    """A frame is kept as a keyframe (a node of the pose graph) only where no keyframe lies within these (m, rad); a
    loop closure adds a factor only once the base moved this far from the last one's (a base standing still is one
    view: in between, an accepted loop-closure registration corrects the filter alone)."""
    keyframe_label_m: float = 0.1
    keyframe_floor_m: float = 0.05
    """A keyframe keeps the frame's points higher than `keyframe_floor_m` (m) that lie within `keyframe_label_m` (m)
    of a surface the map trusts, labelled with its object's id (the arm, noise and untrusted objects stay out)."""
    loop_vouch_s: float = 1.0
    """A loop closure accepted within this long (s of robot time, frame to frame) vouches for the pose: the map's
    objects a registration then finds off their surfaces were placed while the pose drifted (the keyframes are raw
    frames of an earlier visit, placed by the optimised graph), so they leave the reference as change evidence for
    the map to re-place them, instead of putting the pose in doubt (refused as inconsistent) or taking it back onto
    the drifted map (a χ² refusal under a jump's size grows P and the next frame is accepted). It mends the first
    frames after a closure, not a map mapped along a long drift: docs/decisions.md, "A loop closure vouches for the
    pose"."""
    loop_min_age_s: float = 40.0
    """Loop closures go onto keyframes exposed at least this long ago (s of robot time): an earlier visit."""
    loop_search_m: float = 1.0
    loop_search_rad: float = math.radians(60.0)
    """The anchor: the nearest keyframe of an earlier visit within these (m, rad) of the estimate."""
    loop_submap_m: float = 2.0
    """The submap: the earlier visits' keyframes within this (m) of the anchor."""
    loop_radius_max_m: float = 0.6
    loop_fine_radius_m: float = 0.15
    """A loop closure registers first within clip(radius_sigmas σ + radius_margin_m, radius_min_m,
    loop_radius_max_m), σ from odometry and loop closures alone (not the filter's), then again within
    `loop_fine_radius_m` from there."""
    loop_sigma_m: float = 0.03
    loop_sigma_rad: float = 0.01
    """Measurement std (m, rad) of a loop closure along a well-constrained direction (inflated as `sigma_xy_m`)."""
    graph_follows_map: bool = True
    """The pose graph's nodes are tied by the odometry with the map registrations' corrections composed in (the filter's
    trajectory between loop closures); False: by the wheel odometry alone (then a loop closure onto a place mid-lap
    put the lap's nodes back onto the odometry's drift)."""
    graph_odometry_floor_m: float = 0.002
    graph_odometry_floor_rad: float = 0.001
    """Odometry between two nodes is trusted at most to these stds (m, rad), however short the step."""
    graph_iterations: int = 5
    """Gauss–Newton iterations after each loop closure (at most)."""

    def __post_init__(self) -> None:
        check_choices(self)
