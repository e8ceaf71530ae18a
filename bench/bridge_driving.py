"""Live driving through the hardware bridge on a loaded machine, as `python -m app --backend bridge` runs:
a real `BridgeServer` (uvicorn on 127.0.0.1), the reference driver in its own process (MuJoCo in real
time, two depth cameras), a live `Runtime` with the object map and CBF running the two pick-up stops over
and over, and `burners` processes that only burn CPU beside it.

What it measures (the figures of bench/closed_loop.py):
- stale-state pauses of the run, split by cause: the driver itself fell silent (no state sent in the
  140 ms before the event: its process was starved) or the bridge's process did not read what was sent;
- control periods started more than one period late (robot time);
- the velocity command rate and gaps at the bridge (the runtime's `command` calls), commands the bridge's
  outbox superseded before sending;
- faults (none expected) and the CPU time of the runtime's process.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState

ROOT = Path(__file__).parents[1]
DRIVER_SILENT_S = 0.14
"""A stale event with no state sent for this long before it is the driver's own silence (the bridge calls
state stale at 150 ms; one state period of slack)."""


@dataclass
class DrivingResult:
    duration_s: float
    stale_pauses: int = 0
    stale_events: int = 0
    stale_driver_silent: int = 0
    faults: list[str] = field(default_factory=list)
    laps: int = 0
    subtasks_done: int = 0
    subtask_failures: list[str] = field(default_factory=list)
    restarts: list[float] = field(default_factory=list)
    """Monotonic times the supervisor started the run again (after a pause, the end of a lap or a fault)."""
    control_steps: int = 0
    control_late: int = 0
    command_times: list[float] = field(default_factory=list)
    commands_superseded: int = 0
    cpu_s: float = 0.0
    loop_niceness: float = float("nan")
    """Niceness of the live loops' threads (they ask for `RuntimeConfig.live_niceness`, app/thread_priority.py)."""
    driver_niceness: float = float("nan")
    map_niceness: float = float("nan")
    load_before: tuple[float, float, float] = (0.0, 0.0, 0.0)
    load_after: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def figures(self) -> dict[str, float]:
        gaps = np.diff(self.command_times) * 1e3 if len(self.command_times) > 1 else np.array([np.nan])
        return {
            "stale_pauses": float(self.stale_pauses),
            "stale_events": float(self.stale_events),
            "stale_events_driver_silent": float(self.stale_driver_silent),
            "stale_events_bridge_side": float(self.stale_events - self.stale_driver_silent),
            "control_periods_late_pct": 100.0 * self.control_late / max(1, self.control_steps),
            "command_rate_hz": len(self.command_times) / self.duration_s,
            "command_gap_p50_ms": float(np.median(gaps)),
            "command_gap_p99_ms": float(np.percentile(gaps, 99)),
            "command_gap_max_ms": float(np.max(gaps)),
            "commands_superseded": float(self.commands_superseded),
            "bridge_faults": float(len(self.faults)),
            "bridge_laps": float(self.laps),
            "bridge_subtasks_done": float(self.subtasks_done),
            "bridge_subtasks_failed": float(len(self.subtask_failures)),
            "command_gap_max_after_restart_s": self._longest_gap_after_restart(),
            "runtime_cpu_pct": 100.0 * self.cpu_s / self.duration_s,
            "load_average_1min": self.load_after[0],
            "loop_niceness": self.loop_niceness,
            "driver_niceness": self.driver_niceness,
            "map_niceness": self.map_niceness,
        }


    def _longest_gap_after_restart(self) -> float:
        """How long after the latest (re)start the longest command gap began (s; NaN: before any)."""
        if len(self.command_times) < 2:
            return float("nan")
        start = self.command_times[int(np.argmax(np.diff(self.command_times)))]
        before = [t for t in self.restarts if t <= start]
        return start - before[-1] if before else float("nan")


@contextlib.contextmanager
def burning(n: int, niceness: int = 0) -> Iterator[list[subprocess.Popen]]:
    """`n` processes that only burn CPU (at `niceness` below this process's priority), ended on exit."""
    procs = [subprocess.Popen([sys.executable, "-c", f"import os; os.nice({int(niceness)})\nwhile True: pass"])
             for _ in range(n)]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


def _start_driver(bridge: BridgeServer, sent_file: Path, raise_priority: bool) -> subprocess.Popen:
    env = {**os.environ, "HTMPC_BRIDGE_TOKEN": bridge.token}
    niceness = [] if raise_priority else ["--niceness", str(os.getpriority(os.PRIO_PROCESS, 0))]
    proc = subprocess.Popen([sys.executable, "-m", "bench.recording_driver", str(sent_file), "--url",
                             bridge.robot_url, "--log-level", "ERROR", *niceness], cwd=ROOT, env=env)
    if not bridge.robot.wait_for_state(120.0):
        proc.kill()
        raise SystemExit("the sim driver sent no state within 120 s")
    return proc


def _stop_driver(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _supervise(rt: Runtime, result: DrivingResult, duration_s: float) -> None:
    """Keep the sequence running as an operator would: Start again after a pause (counted), after the end
    of the sequence (a lap), and Reset after a fault (counted)."""
    end = time.monotonic() + duration_s
    while time.monotonic() < end:
        time.sleep(0.05)
        state = rt.run_state
        if state == RunState.PAUSED:
            result.stale_pauses += 1
        elif state in (RunState.FINISHED, RunState.FAILED):
            result.laps += 1
            progress = rt.sequencer.progress
            result.subtasks_done += sum(p.outcome.value == "done" for p in progress)
            result.subtask_failures += [f"{p.name}: {p.message}" for p in progress if p.outcome.value == "failed"]
        elif state == RunState.FAULT:
            result.faults.append(rt.fault or "")
            _collect_control(rt, result)
            rt.reset()
        else:
            continue
        result.restarts.append(time.monotonic())
        rt.start()


def _collect_control(rt: Runtime, result: DrivingResult) -> None:
    if rt.live is not None:
        lateness = np.array(rt.live.control_lateness_s)
        result.control_steps += len(lateness)
        result.control_late += int(np.sum(lateness > rt.live.control_period_s))


def _note_niceness(rt: Runtime, driver: subprocess.Popen, result: DrivingResult) -> None:
    """The priorities the run had (app/thread_priority.py): live loops, the driver, the mapping process."""
    def nice(tid: int | None) -> float:
        try:
            return float(os.getpriority(os.PRIO_PROCESS, tid)) if tid else float("nan")
        except OSError:
            return float("nan")

    result.loop_niceness = nice(rt.live.control._thread.native_id) if rt.live else float("nan")
    result.driver_niceness = nice(driver.pid)
    result.map_niceness = nice(getattr(rt.map, "pid", None))


def _driver_silent(stale_at: np.ndarray, sent: np.ndarray) -> int:
    """How many stale events came after the driver had sent nothing for `DRIVER_SILENT_S`."""
    if not len(stale_at) or not len(sent):
        return len(stale_at)
    idx = np.searchsorted(sent, stale_at) - 1
    last = np.where(idx >= 0, sent[np.clip(idx, 0, None)], -np.inf)
    return int(np.sum(stale_at - last > DRIVER_SILENT_S))


def drive(duration_s: float, burners: int = 2, burner_niceness: int = 0, raise_priority: bool = True) -> DrivingResult:
    """Drive through the bridge for `duration_s` with `burners` CPU burners beside it (at `burner_niceness`
    below this process: 0 is the same priority, 10 background work); without `raise_priority`, the runtime
    and the driver stay at this process's priority (`app/thread_priority.py` off: the comparison)."""
    result = DrivingResult(duration_s, load_before=os.getloadavg())
    with tempfile.TemporaryDirectory() as tmp, burning(burners, burner_niceness):
        bridge = BridgeServer(port=0, token=secrets.token_urlsafe(24), token_file=Path(tmp) / "token")
        bridge.start()
        sent_file = Path(tmp) / "sent.npy"
        driver = _start_driver(bridge, sent_file, raise_priority)
        config = RuntimeConfig(map_kind="object")
        rt = Runtime(config if raise_priority else replace(config, live_niceness=None), backend=bridge.robot)
        bridge.attach(rt)
        command = bridge.robot.command
        driving = threading.Event()
        """Commands are timed only while the run is driven (not while the runtime shuts down)."""

        def timed(qdot: np.ndarray, t: float) -> None:
            if driving.is_set():
                result.command_times.append(time.monotonic())
            command(qdot, t)

        bridge.robot.command = timed
        stale_at: list[float] = []
        record = bridge.link.record

        def noting(kind: str, detail: str = ""):
            if kind == "stale":
                stale_at.append(time.monotonic())
            return record(kind, detail)

        bridge.link.record = noting
        try:
            rt.start_live()
            rt.start()
            result.restarts.append(time.monotonic())
            cpu0, superseded0 = time.process_time(), bridge.link.counts["commands_superseded"]
            result.command_times.clear()
            stale_at.clear()
            driving.set()
            _supervise(rt, result, duration_s)
            driving.clear()
            _note_niceness(rt, driver, result)
            result.cpu_s = time.process_time() - cpu0
            _collect_control(rt, result)
            result.commands_superseded = bridge.link.counts["commands_superseded"] - superseded0
        finally:
            rt.shutdown()
            bridge.stop()
            _stop_driver(driver)
        result.stale_events = len(stale_at)
        sent = np.load(sent_file) if sent_file.exists() else np.zeros(0)
        result.stale_driver_silent = _driver_silent(np.array(stale_at), sent)
    result.load_after = os.getloadavg()
    return result
