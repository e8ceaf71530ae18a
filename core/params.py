"""Tunables of the method, in one place, with the paper's names and units (DESIGN.md "Defaults").

Each component takes its own frozen parameter object; `dataclasses.replace` makes a variant.
Values follow METHOD.md (the HTMPC authors' configuration and POCD's reference values) unless a
docstring says why we differ.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class RobotParams:
    """Geometry and limits of the UR10 on an omnidirectional (Ridgeback-like) base."""

    arm_mount_xyz_m: tuple[float, float, float] = (0.27, 0.0, 0.653)
    """Position of the UR10 `base_link` in the base frame (Ridgeback top plate plus riser)."""
    base_size_m: tuple[float, float, float] = (0.96, 0.79, 0.32)
    """Ridgeback footprint (length, width) and body height."""
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
    noise_std_m: float = 0.0
    """Std of additive Gaussian depth noise, scaled by depth² (stereo-like) at 1 m."""
    rate_hz: float = 10.0


@dataclass(frozen=True)
class SimParams:
    """The MuJoCo world."""

    timestep_s: float = 0.002
    """500 Hz physics (paper: commands at 100 Hz)."""
    walls: bool = False
    room_half_size_m: float = 6.0
    hand_camera: CameraParams = field(default_factory=CameraParams)
    base_camera: CameraParams = field(default_factory=CameraParams)
    odometry_noise_std_m: float = 0.0
    odometry_noise_std_rad: float = 0.0
    box_pool: int = 32
    """Boxes pre-allocated as hidden mocap bodies; adding beyond the pool recompiles (grows it ×2)."""
    distance_margin_m: float = 2.0
    """Robot–box distances beyond this are reported as this value (saves narrow-phase work)."""


@dataclass(frozen=True)
class HTMPCParams:
    """Lexicographic MPC and CBF (METHOD.md "Reference controller settings")."""

    N: int = 10
    dt_s: float = 0.3
    gamma: float = 1.0
    """CBF decay rate: dh/dt ≥ −gamma h. Smaller is more cautious."""
    delta_safe_m: float = 0.25
    constraint: str = "cbf"
    """'cbf' (eq. 10) or 'edf' (h ≥ 0 baseline)."""
    lex_tolerance: float = 0.01
    """Added to the stored |e_i*| in (7c)."""
    slack_linear: float = 50.0
    slack_quadratic: float = 1.0
    Q_base: tuple[float, float, float] = (1.0, 1.0, 0.5)
    Q_ee: tuple[float, float, float, float, float, float] = (1.0, 1.0, 1.0, 0.2, 0.2, 0.2)
    Q_edot: float = 0.01
    Q_x: float = 1e-3
    Q_u: float = 1e-2
    sqp_iters: int = 1
    sqp_iters_on_switch: int = 5
    control_rate_hz: float = 10.0
    command_rate_hz: float = 100.0


@dataclass(frozen=True)
class MappingParams:
    """Object-level map (POCD) and local EDF."""

    voxel_m: float = 0.05
    """Object submap resolution (POCD: 5 cm)."""
    tau_m: float = 0.2
    delta_max_m: float = 4.0
    theta_stat: float = 0.4
    """Remove an object when E[v] < theta_stat after more than `min_observations` observations."""
    min_observations: int = 2
    alpha0: float = 2.0
    beta0: float = 1.0
    mu0_m: float = 0.0
    sigma0_m: float = 0.5
    beta_cap: float = 25.0
    semantic_weight_k: float = 0.0
    floor_height_m: float = 0.03
    edf_window_m: tuple[float, float, float] = (4.0, 4.0, 1.4)
    edf_voxel_m: float = 0.1
    theta_cutoff_m: float = 1.8
    theta_zero_m: float = 0.05
    range_m: float = 3.0


@dataclass(frozen=True)
class SequencerParams:
    """Turning the active subtask into HTMPC references (tasks/), and base path planning."""

    nominal_speed_mps: float = 0.6
    """Speed at which base references advance along the planned path."""
    lookahead_m: float = 1.5
    """In navigation the hand camera looks at the path point this far ahead."""
    grid_cell_m: float = 0.1
    inflation_m: float = 0.6
    """Obstacles are grown by this radius for A* (base sphere 0.55 m plus a little)."""
    obstacle_z_m: tuple[float, float] = (0.05, 2.0)
    """Occupied points between these heights block the base."""
    replan_period_s: float = 1.0
    goal_slowdown_m: float = 0.8
    """Within this distance of the final goal the reference stops advancing past it."""
