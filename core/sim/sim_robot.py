"""`SimRobot`: the MuJoCo world behind the `RobotBackend` protocol, plus lockstep `step(dt)`.

Cameras render at their own rate in simulated time; `observe()` hands over the frames captured since
the previous call. Odometry reports the base pose with optional Gaussian noise. A command older than
`command_timeout_s` is dropped to zero velocity, as a real base's watchdog would.
"""

from __future__ import annotations

import logging

import numpy as np

from core.sim.depth_camera import DepthCamera
from core.sim.world import SimWorld
from core.types import DepthFrame, Observation, Odometry, RobotState

log = logging.getLogger(__name__)


class SimRobot:
    """A simulated robot: commands in, observations out, physics advanced by `step`."""

    def __init__(self, world: SimWorld, seed: int = 0, cameras: tuple[str, ...] = ("hand", "base"),
                 command_timeout_s: float = 0.5) -> None:
        self.world = world
        params = world.params
        self._rng = np.random.default_rng(seed)
        cam_params = {"hand": params.hand_camera, "base": params.base_camera}
        self.cameras = {name: DepthCamera(world, name, cam_params[name], seed=seed + i)
                        for i, name in enumerate(cameras)}
        self._next_render = {name: world.time for name in self.cameras}
        self._frames: list[DepthFrame] = []
        self._last_command_t = -np.inf
        self._command = np.zeros(9)
        self.command_timeout_s = command_timeout_s
        self.rejected_commands = 0

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
        self.world.set_velocity_command(self._command)

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
            due = min([*self._next_render.values(), deadline])
            n = remaining
            if np.isfinite(due):
                n = int(np.clip(np.ceil((due - self.world.time) / h - 1e-6), 1, remaining))
            self.world.step(n)
            remaining -= n
            self._render_due()

    def _check_watchdog(self) -> None:
        if np.any(self._command) and self.world.time - self._last_command_t > self.command_timeout_s - 1e-9:
            log.warning("no command for %.2f s: stopping", self.command_timeout_s)
            self._command = np.zeros(9)
            self.world.set_velocity_command(self._command)

    def _render_due(self) -> None:
        t = self.world.time
        for name, cam in self.cameras.items():
            if t + 1e-9 >= self._next_render[name]:
                self._frames.append(cam.render())
                self._next_render[name] += 1.0 / cam.params.rate_hz
                if self._next_render[name] <= t:
                    self._next_render[name] = t + 1.0 / cam.params.rate_hz

    def odometry(self, state: RobotState) -> Odometry:
        """Base pose and twist, with the configured Gaussian noise."""
        p = self.world.params
        noise = self._rng.normal(0.0, 1.0, 3) * [p.odometry_noise_std_m, p.odometry_noise_std_m,
                                                  p.odometry_noise_std_rad]
        return Odometry(state.t, state.q[:3] + noise, state.v[:3].copy())

    def observe(self) -> Observation:
        """Joint state, odometry and the frames captured since the last call."""
        state = self.world.state()
        frames, self._frames = tuple(self._frames), []
        return Observation(state=state, frames=frames, odometry=self.odometry(state))

    def close(self) -> None:
        """Free the cameras' GL resources (call from the thread that rendered)."""
        for cam in self.cameras.values():
            cam.close()
