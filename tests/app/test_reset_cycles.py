"""Start/Stop/E-stop/Reset cycles on a live runtime (real MuJoCo, real map worker): a Reset hands the running
map worker on, never one it has just killed, and kills it only to free a thread that waits on it. Issue 32's
faults ('mapping loop: MapProcessError: the mapping process is gone (EOFError)'): a Reset that found any loop
slow to stop (physics making GL contexts on a loaded machine) killed the worker, and the next loop could be
handed that dying worker."""

from __future__ import annotations

import gc
import multiprocessing
import threading

import numpy as np
import pytest

import tests.app.faults as faults
from app.runtime.map_process import MapProcess, MapProcessError
from app.runtime.snapshot import RunState
from core.mapping import ObjectMapper
from core.params import MappingParams
from core.robot.model import RobotModel
from tests.app.bridge.conftest import wait_until
from tests.app.faults import PATIENT, faulty_runtime

pytestmark = pytest.mark.wallclock


def _isolated(rt) -> MapProcess | None:
    world_map = rt.map
    return world_map if isinstance(world_map, MapProcess) and world_map.isolated else None


def _gl_contexts() -> int:
    return sum(1 for o in gc.get_objects() if type(o).__name__ == "GLContext" and getattr(o, "_context", None))


def test_an_aborted_worker_is_never_handed_on() -> None:
    """Killed while it still imports (the map works here meanwhile): `is_alive` says True until the kernel has
    reaped it, and `adopt` used to take the next map without a word; the next integrate found the pipe closed."""
    robot = RobotModel()
    process = MapProcess(ObjectMapper(robot, MappingParams()))
    assert not process.isolated
    process.abort()
    assert not process.alive
    with pytest.raises(MapProcessError, match="closed or gone"):
        process.adopt(ObjectMapper(robot, MappingParams()))
    process.close(keep=False)


def test_a_reset_while_physics_is_slow_to_stop_keeps_the_map_worker(monkeypatch) -> None:
    monkeypatch.setattr(faults, "HANG_S", 4.0)  # longer than one join (3 s), shorter than two
    rt, backend = faulty_runtime("object", htmpc=PATIENT)
    rt.start_live()
    try:
        assert wait_until(lambda: _isolated(rt) is not None, timeout_s=120), "the map never moved to its worker"
        worker = _isolated(rt)
        assert worker is not None
        pid = worker.pid
        backend.arm("step", "hang", 1)
        assert wait_until(lambda: backend._fault is None, timeout_s=10)  # the physics thread is in the hang
        rt.reset()
        assert rt.map is worker and worker.pid == pid and worker.alive  # handed on, not killed
        rt.start()
        assert wait_until(lambda: rt.state.v[0] > 0.1, timeout_s=60), rt.status_line()
        rt.stop()
        assert rt.fault is None and rt.run_state == RunState.IDLE
    finally:
        rt.shutdown()


@pytest.mark.slow
def test_start_stop_estop_reset_cycles_end_clean() -> None:
    """30 cycles as bench/soak.py's api_cycles runs them (through the runtime instead of HTTP): none ends in a
    fault, the worker stays the same process, no thread, child process or GL context is left over."""
    rt, _ = faulty_runtime("object", htmpc=PATIENT)
    rt.start_live()
    try:
        worker = rt.map
        assert isinstance(worker, MapProcess)
        threads, children, contexts = threading.active_count(), multiprocessing.active_children(), _gl_contexts()
        faults_seen = []
        for i in range(30):
            rt.start()
            assert wait_until(lambda: rt.plan is not None, timeout_s=30) or rt.fault, rt.status_line()
            rt.stop() if i % 2 == 0 else rt.emergency_stop()
            if rt.fault:
                faults_seen.append(f"cycle {i}: {rt.fault}")
            rt.reset()
            assert wait_until(lambda: rt.live is not None and rt.state.t > 0.2, timeout_s=30)
        assert not faults_seen
        assert rt.map is worker and worker.alive
        assert wait_until(lambda: threading.active_count() <= threads, timeout_s=10)
        assert {p.pid for p in multiprocessing.active_children()} == {p.pid for p in children}
        assert wait_until(lambda: _gl_contexts() <= contexts, timeout_s=10)
        assert np.all(np.isfinite(rt.state.q))
    finally:
        rt.shutdown()
    assert wait_until(lambda: not multiprocessing.active_children(), timeout_s=30)  # reaped (slow under load)


def test_slow_camera_setup_after_a_reset_is_no_physics_stall(monkeypatch) -> None:
    """Every Reset makes the cameras' GL contexts anew, which took seconds under load: the physics watchdog
    counts from when they exist (the other loops wait for them, `CAMERA_SETUP_WAIT_S`), not from the thread's
    start, which faulted the new run ('physics loop stalled')."""
    import time

    from core.sim.sim_robot import SimRobot

    prepare = SimRobot.prepare_cameras

    def slow(self: SimRobot) -> None:
        time.sleep(6.0)  # longer than the physics loop's stall limit (5 s)
        prepare(self)

    rt, _ = faulty_runtime()
    rt.start_live()
    try:
        monkeypatch.setattr(SimRobot, "prepare_cameras", slow)
        rt.reset()
        time.sleep(1.0)  # a few watchdog periods after the other loops started
        assert rt.fault is None, rt.fault
    finally:
        rt.shutdown()


def _rendered_since(rt, t: float) -> bool:
    """Whether every camera has delivered a frame taken after robot time `t`."""
    frames = rt.latest_frames
    return bool(frames) and min(f.t for f in frames.values()) > t


def test_a_reset_renders_with_the_renderers_the_previous_physics_thread_made() -> None:
    """Every Reset starts a new physics thread; it renders with the cameras' renderers (a GL context each) that
    the first one made, not new ones: made anew and freed every Reset, they grew native memory by about 0.1 MB
    a Reset that no collection or trim gave back (issue 32). Shutdown frees them."""
    rt, backend = faulty_runtime("ground_truth")
    rt.start_live()
    try:
        renderers = {name: cam._renderer for name, cam in backend.cameras.items()}
        assert all(r is not None for r in renderers.values())
        contexts = _gl_contexts()
        for _ in range(3):
            rt.reset()
            assert wait_until(lambda t=rt.state.t: _rendered_since(rt, t + 0.2), timeout_s=30), rt.status_line()
            assert rt.fault is None, rt.fault
            assert {name: cam._renderer for name, cam in backend.cameras.items()} == renderers
        assert _gl_contexts() == contexts
    finally:
        rt.shutdown()
    assert all(cam._renderer is None for cam in backend.cameras.values())
