"""`SimRobot`: the MuJoCo world behind the `RobotBackend` protocol, plus lockstep `step(dt)`.

It declares what it can do (`abilities`): the runtime steps it in lockstep (`SteppableBackend`), it is a
simulation whose world the runtime may edit and read the truth of (`SimulatedBackend`), and it knows its
cameras' latency exactly (the sensor model's `camera_time_offset_s`).

Cameras render at their own rate in simulated time; `observe()` hands over the frames captured since
the previous call. A command older than `command_timeout_s` is dropped to zero velocity, as a real
base's watchdog would.

The robot perceives through the sensor model (`SensorParams`, the world's by default): its cameras
report depth as real ones do (`depth_artefacts.py`); its base pose is dead reckoning that drifts
(`odometry_drift.py`), and everything it reports is in the world it believes in: the state's base
pose and velocity, the cameras' poses; the base velocities it is commanded in that world are turned
into the true one. A frame taken at t is stamped t + `camera_time_offset_s` and delivered then, at the
camera pose the robot estimates at the stamp. The world (`SimWorld`) keeps the truth, for the
simulator's own measurements.
"""

from __future__ import annotations

import logging

import numpy as np

from core.params import SensorParams
from core.sim.depth_camera import DepthCamera
from core.sim.odometry_drift import DriftingOdometry
from core.sim.world import SimWorld
from core.types import BackendAbilities, DepthFrame, Observation, Odometry, RobotState

log = logging.getLogger(__name__)


class SimRobot:
    """A simulated robot: commands in, observations out, physics advanced by `step`."""

    def __init__(self, world: SimWorld, seed: int = 0, cameras: tuple[str, ...] = ("hand", "base"),
                 command_timeout_s: float = 0.5, sensor: SensorParams | None = None) -> None:
        self.world = world
        params = world.params
        cam_params = {"hand": params.hand_camera, "base": params.base_camera}
        self.cameras = {name: DepthCamera(world, name, cam_params[name], seed=seed + i)
                        for i, name in enumerate(cameras)}
        self._seed = seed
        self.set_sensor(sensor or params.sensor)
        self._next_render = {name: world.time for name in self.cameras}
        self._taken: list[tuple[float, str, np.ndarray]] = []
        """Images taken and not yet stamped: (stamp time, camera, depth)."""
        self._frames: list[DepthFrame] = []
        self._last_command_t = -np.inf
        self._command = np.zeros(9)
        self.command_timeout_s = command_timeout_s
        self.rejected_commands = 0

    def set_sensor(self, sensor: SensorParams) -> None:
        """Perceive through `sensor` from now on; the pose estimate restarts at the true pose."""
        self.sensor = sensor
        for cam in self.cameras.values():
            cam.sensor = sensor
        self.odometry_estimate = DriftingOdometry(sensor.odometry_drift_m, sensor.odometry_drift_rad,
                                                  np.random.default_rng([self._seed, 1]))
        self._placements = -1
        self._slipped = False
        self._sync_odometry()

    @property
    def abilities(self) -> BackendAbilities:
        """Stepped in lockstep, simulated, and stamping frames late by the sensor model's camera offset."""
        return BackendAbilities(steps_in_lockstep=True, simulated=True,
                                camera_latency_s=self.sensor.camera_time_offset_s)

    @property
    def time(self) -> float:
        return self.world.time

    def command(self, qdot: np.ndarray, t: float) -> None:
        """Velocity command qdot[9] (world-frame base rates, arm joint rates) stamped t (s)."""
        qdot = np.asarray(qdot, dtype=float)
        if qdot.shape != (9,) or not np.all(np.isfinite(qdot)):
            self.rejected_commands += 1
            log.warning("rejected command %r: need 9 finite numbers; stopping", qdot)
            qdot = np.zeros(9)
        self._command = self.world.robot.limits.clip_velocity(qdot)
        self._last_command_t = self.world.time
        self._apply(self._command)

    def _apply(self, qdot: np.ndarray) -> None:
        """Hand a command of the believed world to the actuators (base x-y rotated into the true world)."""
        true = qdot.copy()
        true[:2] = self.odometry_estimate.to_true(qdot[:2])
        self.world.set_velocity_command(true)

    def stop(self) -> None:
        """Zero velocity now."""
        self.command(np.zeros(9), self.world.time)

    def step(self, dt: float) -> None:
        """Advance the simulation by dt (s) in physics steps, rendering cameras when they are due and
        dropping a stale command at its deadline."""
        h = self.world.params.timestep_s
        remaining = max(1, int(round(dt / h)))
        while remaining > 0:
            self._check_watchdog()
            deadline = self._last_command_t + self.command_timeout_s if np.any(self._command) else np.inf
            due = min([*self._next_render.values(), *(t for t, _, _ in self._taken), deadline])
            n = remaining
            if np.isfinite(due):
                n = int(np.clip(np.ceil((due - self.world.time) / h - 1e-6), 1, remaining))
            self.world.step(n)
            remaining -= n
            self._sync_odometry()
            self._render_due()
            self._stamp_due()

    def prepare_cameras(self) -> None:
        """Make every camera's renderers now unless they exist, from the thread that steps and renders
        (`DepthCamera.prepare`)."""
        for cam in self.cameras.values():
            cam.prepare()

    def _check_watchdog(self) -> None:
        if np.any(self._command) and self.world.time - self._last_command_t > self.command_timeout_s - 1e-9:
            log.warning("no command for %.2f s: stopping", self.command_timeout_s)
            self._command = np.zeros(9)
            self._apply(self._command)

    def _sync_odometry(self) -> None:
        """Advance the base pose estimate to now (restart it after a teleport)."""
        q = self.world.state().q
        if self.world.placements != self._placements:
            self._placements = self.world.placements
            self.odometry_estimate.reset(q[:3])
        else:
            self.odometry_estimate.update(q[:3])
        slip_at = self.sensor.slip_at_s
        if not self._slipped and slip_at is not None and self.world.time + 1e-9 >= slip_at:
            self._slipped = True  # once: the sensor model's one-off odometry error (`SensorParams.slip_at_s`)
            self.odometry_estimate.slip(self.sensor.slip_m, self.sensor.slip_rad)

    def _render_due(self) -> None:
        t = self.world.time
        for name, cam in self.cameras.items():
            if t + 1e-9 >= self._next_render[name]:
                taken_t, depth = cam.capture()
                self._taken.append((taken_t + self.sensor.camera_time_offset_s, name, depth))
                self._next_render[name] += 1.0 / cam.params.rate_hz
                if self._next_render[name] <= t:
                    self._next_render[name] = t + 1.0 / cam.params.rate_hz

    def _stamp_due(self) -> None:
        """Deliver the images whose stamp time has come, at the camera pose estimated now (the stamp)."""
        t = self.world.time
        due = [x for x in self._taken if x[0] <= t + 1e-9]
        if not due:
            return
        self._taken = [x for x in self._taken if x[0] > t + 1e-9]
        q = self.state().q
        for stamp, name, depth in due:
            self._frames.append(self.cameras[name].frame(stamp, depth, self.world.robot.camera_pose(q, name)))

    def true_state(self) -> RobotState:
        """The simulator's exact joint state (what the robot does not know)."""
        return self.world.state()

    def state(self) -> RobotState:
        """Joint state as the robot knows it: base pose and velocity in the world it believes in."""
        true = self.world.state()
        if self.world.placements != self._placements:
            self._sync_odometry()
        q, v = true.q.copy(), true.v.copy()
        est = self.odometry_estimate
        q[:3] = est.estimate
        v[:2] = est.to_estimate(true.v[:2])
        return RobotState(true.t, q, v)

    def odometry(self, state: RobotState) -> Odometry:
        """Base pose and twist as the robot estimates them."""
        return Odometry(state.t, state.q[:3].copy(), state.v[:3].copy())

    def observe(self) -> Observation:
        """Joint state, odometry and the frames delivered since the last call (all as the robot knows them)."""
        state = self.state()
        frames, self._frames = tuple(self._frames), []
        return Observation(state=state, frames=frames, odometry=self.odometry(state))

    def close(self) -> None:
        """Free the cameras' GL resources, once no thread renders any more (the next render makes them anew)."""
        for cam in self.cameras.values():
            cam.close()
