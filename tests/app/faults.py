"""Fault injection into real parts: a `SimRobot` that records every command and can fail on demand, a
wrapper that makes one method of a real component raise from its k-th call, and the checks a safe stop
must pass."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from app.runtime import Runtime, RuntimeConfig
from core.params import HTMPCParams
from core.robot.model import RobotModel
from core.scene import Scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld
from core.types import Observation
from tasks import BasePose, BaseSubtask, TaskSequence

DRIVE = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0), timeout_s=60.0)])
"""Straight ahead over an empty floor: the base is at speed within 2 s."""
HANG_S = 3.0
PATIENT = HTMPCParams(solve_timeout_ms=5000.0)
"""Live tests on a loaded machine: slow solves are not what they test."""


class FaultyRobot(SimRobot):
    """The MuJoCo robot, recording every command (robot time, qdot); `arm(...)` makes `observe` or `step`
    raise, or `observe` return a non-finite state, for the next `calls` calls."""

    def __init__(self, world: SimWorld) -> None:
        super().__init__(world)
        self.commands: list[tuple[float, np.ndarray, bool]] = []
        """(robot time, qdot, whether the run was faulted when it was sent), in order."""
        self.faulted: Callable[[], bool] = lambda: False
        self._lock = threading.Lock()
        self._fault: tuple[str, object, int] | None = None

    def arm(self, method: str, fault: object, calls: int = 10**9) -> None:
        """From now on, `method` ('observe' or 'step') fails with `fault` for `calls` calls: an exception is
        raised, 'nan'/'inf' make the observed joint positions/velocities non-finite, 'hang' (step) sleeps."""
        with self._lock:
            self._fault = (method, fault, calls)

    def _due(self, method: str) -> object | None:
        with self._lock:
            if self._fault is None or self._fault[0] != method:
                return None
            _, fault, calls = self._fault
            self._fault = (method, fault, calls - 1) if calls > 1 else None
            return fault

    def command(self, qdot: np.ndarray, t: float) -> None:
        with self._lock:
            self.commands.append((float(t), np.array(qdot, dtype=float), self.faulted()))
        super().command(qdot, t)

    def step(self, dt: float) -> None:
        fault = self._due("step")
        if isinstance(fault, BaseException):
            raise fault
        if fault == "hang":
            time.sleep(HANG_S)
        super().step(dt)

    def observe(self) -> Observation:
        fault = self._due("observe")
        if isinstance(fault, BaseException):
            raise fault
        obs = super().observe()
        if fault in ("nan", "inf"):
            bad = np.full(9, np.nan if fault == "nan" else np.inf)
            obs = replace(obs, state=replace(obs.state, q=bad if fault == "nan" else obs.state.q,
                                             v=bad if fault == "inf" else obs.state.v))
        return obs

    def braking_commands(self) -> tuple[np.ndarray, np.ndarray]:
        """Times and commands from the last one before the fault on."""
        with self._lock:
            first = next(i for i, c in enumerate(self.commands) if c[2])
            rows = self.commands[max(0, first - 1):]
        return np.array([r[0] for r in rows]), np.array([r[1] for r in rows]).reshape(-1, 9)


class RaiseOnCall:
    """A real component whose `method` raises `error` from its k-th call on (or, with `error` None, only
    that call takes `sleep_s` longer); everything else passes through."""

    def __init__(self, inner: object, method: str, error: BaseException | None, k: int = 1,
                 sleep_s: float = 0.0) -> None:
        self._inner, self._method, self._error, self._k, self._sleep_s = inner, method, error, k, sleep_s
        self.calls = 0

    def __getattr__(self, name: str):
        attr = getattr(self._inner, name)
        if name != self._method:
            return attr

        def call(*args, **kwargs):
            self.calls += 1
            if self.calls >= self._k and self._error is not None:
                raise self._error
            if self.calls == self._k:
                time.sleep(self._sleep_s)
            return attr(*args, **kwargs)
        return call

    def __setattr__(self, name: str, value) -> None:
        if name.startswith("_") or name == "calls":
            object.__setattr__(self, name, value)
        else:
            setattr(self._inner, name, value)


def faulty_runtime(map_kind: str = "ground_truth", htmpc: HTMPCParams | None = None) -> tuple[Runtime, FaultyRobot]:
    robot = RobotModel()
    world = SimWorld(robot, scene=Scene())
    backend = FaultyRobot(world)
    config = RuntimeConfig(map_kind=map_kind, htmpc=htmpc or HTMPCParams())
    rt = Runtime(config, sequence=DRIVE, backend=backend)
    backend.faulted = lambda: rt.fault is not None
    return rt, backend


def assert_brakes_within_limits(rt: Runtime, backend: FaultyRobot) -> None:
    """Every command from the last one before the fault on is finite and within the velocity limits, changes
    by at most a_max per second of robot time, and the last one is zero."""
    lim = rt.robot.limits
    t, qdot = backend.braking_commands()
    assert len(t) >= 2, "no commands after the fault"
    assert np.all(np.isfinite(qdot))
    assert np.all(np.abs(qdot) <= lim.v_max + 1e-9)
    assert np.all(np.hypot(qdot[:, 0], qdot[:, 1]) <= lim.planar_speed + 1e-9)
    dt = np.diff(t)
    dv = np.abs(np.diff(qdot, axis=0))
    moved = dt > 1e-9
    accel = dv[moved] / dt[moved, None]
    assert np.all(accel <= lim.a_max * (1 + 1e-6) + 1e-6), f"deceleration {accel.max(axis=0)} > a_max {lim.a_max}"
    assert np.all(dv[~moved] <= 1e-12), "the command jumped while robot time stood still"
    assert not np.any(qdot[-1]), f"still commanding {qdot[-1]}"
