"""Fault injection into each live loop (real MuJoCo, real threads): a fault anywhere brakes the robot within
its limits, shows the reason in the published snapshots, leaves no loop silently dead, refuses Start until
Reset, and Reset starts every loop anew."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from app.runtime.closed_loop import FaultError
from app.runtime.snapshot import RunState, Snapshot
from tests.app.bridge.conftest import wait_until
from tests.app.faults import PATIENT, RaiseOnCall, assert_brakes_within_limits, faulty_runtime

pytestmark = pytest.mark.wallclock


def _break_part(part: str, method: str, error: BaseException):
    def inject(rt, backend) -> None:
        loop = rt.closed_loop
        setattr(loop, part, RaiseOnCall(getattr(loop, part), method, error))
    return inject


LOOP_FAULTS = {
    "physics": (lambda rt, backend: backend.arm("step", RuntimeError("mujoco broke"), 1),
                "physics loop: RuntimeError: mujoco broke"),
    "io": (lambda rt, backend: backend.arm("observe", OSError("link down"), 3), "io loop: observe: OSError: link down"),
    "io NaN state": (lambda rt, backend: backend.arm("observe", "nan", 3), "non-finite robot state"),
    "mapping": (_break_part("map", "integrate", ValueError("integrate broke")),
                "mapping loop: ValueError: integrate broke"),
    "control": (_break_part("controller", "solve", RuntimeError("solver broke")),
                "control loop: RuntimeError: solver broke"),
    "publish": (_break_part("map", "snapshot", KeyError("objects")), "map snapshot: KeyError"),
    "stalled physics": (lambda rt, backend: _hang_physics(rt, backend), "physics loop stalled"),
    "late control": (lambda rt, backend: setattr(rt.closed_loop, "controller", RaiseOnCall(
        rt.closed_loop.controller, "solve", None, sleep_s=3.0)), "control is late: no control step for 2"),
}


def _hang_physics(rt, backend) -> None:
    """One physics step hangs for 3 s; the watchdog's patience is cut to 1.5 s so the test stays short."""
    next(loop for loop in rt.live.loops if loop.name == "physics").stall_after_s = 1.5
    backend.arm("step", "hang", 1)


def _drive_then_fault(case: str):
    inject, reason = LOOP_FAULTS[case]
    rt, backend = faulty_runtime(htmpc=PATIENT)
    snaps: list[Snapshot] = []
    rt.subscribe(snaps.append)
    rt.start_live()
    rt.start()
    assert wait_until(lambda: rt.state.v[0] > 0.3, timeout_s=60), rt.status_line()
    inject(rt, backend)
    assert wait_until(lambda: rt.fault is not None, timeout_s=15), "no fault"
    return rt, backend, snaps, reason


@pytest.mark.slow
@pytest.mark.parametrize("case", list(LOOP_FAULTS))
def test_a_fault_in_a_live_loop_brakes_and_reset_rebuilds_every_loop(case):
    rt, backend, snaps, reason = _drive_then_fault(case)
    try:
        assert reason in rt.fault and rt.run_state == RunState.FAULT
        assert wait_until(rt.closed_loop.braked, timeout_s=15), "the robot did not come to rest"
        assert_brakes_within_limits(rt, backend)
        assert wait_until(lambda: np.abs(rt.state.v).max() < 0.05, timeout_s=10)
        assert all(loop.alive for loop in rt.live.loops) and rt.live.watchdog.alive, "a loop died"
        assert wait_until(lambda: any(s.fault == rt.fault and s.run_state == RunState.FAULT for s in snaps), 5)
        with pytest.raises(FaultError, match="Reset"):
            rt.start()
        old_loops = list(rt.live.loops)
        rt.reset()
        assert rt.fault is None and rt.run_state == RunState.IDLE
        assert not any(loop.alive for loop in old_loops)
        assert all(loop.alive for loop in rt.live.loops)
        rt.start()
        assert wait_until(lambda: rt.state.v[0] > 0.3, timeout_s=60), \
            f"Start after Reset did not drive: t = {rt.time}, {rt.status_line()}, {rt.live.stats()}"
    finally:
        rt.shutdown()


@pytest.mark.slow
def test_a_loop_that_ends_is_a_fault_not_a_silent_death():
    rt, backend = faulty_runtime(htmpc=PATIENT)
    exits = [SystemExit("subscriber quit")]

    def leave(snap: Snapshot) -> None:
        if exits:
            raise exits.pop()

    rt.start_live()
    try:
        rt.subscribe(leave)
        assert wait_until(lambda: rt.fault is not None, timeout_s=10)
        assert rt.fault == "publish loop ended: SystemExit: subscriber quit"
        publish = next(loop for loop in rt.live.loops if loop.name == "publish")
        assert wait_until(lambda: not publish.alive, timeout_s=5)
        rt.reset()
        assert all(loop.alive for loop in rt.live.loops) and rt.fault is None
        published = rt.live.stats()["publish"].iterations
        assert wait_until(lambda: rt.live.stats()["publish"].iterations > published + 5, timeout_s=10)
    finally:
        rt.shutdown()


def test_the_cameras_are_made_by_the_physics_thread_before_the_other_loops_start(monkeypatch):
    """Making a camera's GL context holds the GIL for ~0.3 s: a control step running meanwhile waited it out
    and overran its 250 ms budget. So the physics thread, which renders, makes them first, and `start_live`
    starts the other loops only then."""
    from app.runtime import Runtime, RuntimeConfig
    from core.sim.sim_robot import SimRobot

    made_in: list[str] = []
    prepare = SimRobot.prepare_cameras

    def record(self: SimRobot) -> None:
        made_in.append(threading.current_thread().name)
        prepare(self)

    monkeypatch.setattr(SimRobot, "prepare_cameras", record)
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"))
    rt.start_live()
    try:
        assert made_in == ["physics"]
        cameras = rt.backend.cameras.values()
        assert cameras and all(cam._renderer is not None for cam in cameras)
        assert all(loop.alive for loop in rt.live.loops)
    finally:
        rt.shutdown()
