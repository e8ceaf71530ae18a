"""Fault injection into the lockstep closed loop (real MuJoCo, real map and controller, one part made to
fail): the robot brakes along its plan within the acceleration limits, the run holds a `fault` with the
reason, Start is refused until Reset, and Reset recovers."""

from __future__ import annotations

import numpy as np
import pytest

from app import cli
from app.runtime.closed_loop import FaultError
from app.runtime.snapshot import RunState
from tasks.sequence_file import EXAMPLES_DIR
from tests.app.faults import RaiseOnCall, assert_brakes_within_limits, faulty_runtime


def _break_part(part: str, method: str, error: BaseException):
    def inject(rt, backend) -> None:
        loop = rt.closed_loop
        setattr(loop, part, RaiseOnCall(getattr(loop, part), method, error))
    return inject


def _arm(method: str, fault: object, calls: int):
    return lambda rt, backend: backend.arm(method, fault, calls)


CASES = {
    "map.integrate RuntimeError": (_break_part("map", "integrate", RuntimeError("integrate broke")),
                                   "mapping: RuntimeError: integrate broke"),
    "map.local_edf ValueError": (_break_part("map", "local_edf", ValueError("edf broke")),
                                 "control: ValueError: edf broke"),
    "controller.solve RuntimeError": (_break_part("controller", "solve", RuntimeError("solver broke")),
                                      "control: RuntimeError: solver broke"),
    "controller.solve KeyError": (_break_part("controller", "solve", KeyError("level")), "control: KeyError"),
    "NaN joint state": (_arm("observe", "nan", 5), "non-finite robot state"),
    "inf joint velocity": (_arm("observe", "inf", 5), "non-finite robot state"),
    "observe raises": (_arm("observe", ConnectionError("link down"), 5), "observe: ConnectionError: link down"),
    "physics step raises": (_arm("step", RuntimeError("mujoco broke"), 1), "physics: RuntimeError: mujoco broke"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_fault_brakes_within_limits_and_holds_until_reset(case):
    inject, reason = CASES[case]
    rt, backend = faulty_runtime()
    rt.run_lockstep(1.5, until_done=False)
    assert rt.state.v[0] > 0.3, "the base should be at speed when the fault strikes"
    t_fault = rt.time
    inject(rt, backend)
    log = rt.run_lockstep(10.0)
    assert rt.run_state == RunState.FAULT and reason in rt.fault
    assert rt.time < t_fault + 3.0, "a faulted run ends once the robot has braked"
    assert_brakes_within_limits(rt, backend)
    assert np.abs(rt.state.v).max() < 0.05, "the robot should be at rest"
    assert [e.kind for e in log.events] == ["fault"] and log.summary()["faults"] == 1.0
    snap = rt.publish()
    assert snap.run_state == RunState.FAULT and snap.fault == rt.fault and "FAULT" in snap.status
    with pytest.raises(FaultError, match="Reset"):
        rt.start()
    with pytest.raises(FaultError):
        rt.run_lockstep(1.0)
    rt.reset()
    assert rt.fault is None and rt.run_state == RunState.IDLE
    rt.run_lockstep(1.0, until_done=False)
    assert rt.run_state == RunState.RUNNING and rt.state.v[0] > 0.2, "Reset should recover a runnable loop"


def test_a_fault_in_an_idle_run_holds_still_and_refuses_start():
    rt, backend = faulty_runtime()
    backend.arm("observe", "nan", 1)
    rt.closed_loop.tick(0.01, control=True)
    assert rt.run_state == RunState.FAULT and "non-finite" in rt.fault
    assert not np.any(backend.commands[-1][1])
    with pytest.raises(FaultError):
        rt.start()


def test_the_emergency_stop_stays_immediate_and_keeps_the_fault():
    rt, backend = faulty_runtime()
    rt.run_lockstep(1.0, until_done=False)
    rt.emergency_stop()
    assert rt.run_state == RunState.ESTOP and not np.any(backend.commands[-1][1])  # zero at once
    rt.closed_loop.fault("test fault")
    rt.emergency_stop()
    assert rt.run_state == RunState.ESTOP and rt.fault == "test fault"
    with pytest.raises(FaultError, match="test fault"):
        rt.start()


def test_headless_run_with_a_fault_exits_non_zero_with_one_line(tmp_path, monkeypatch, capsys):
    import app.runtime.closed_loop

    real = app.runtime.closed_loop.make_map
    monkeypatch.setattr(app.runtime.closed_loop, "make_map", lambda *a: RaiseOnCall(real(*a), "local_edf",
                                                                          ValueError("edf broke"), k=30))
    code = cli.main(["run", "--headless", "--map", "ground_truth", "--sequence",
                     str(EXAMPLES_DIR / "navigation_through_boxes.yaml"), "--max-duration", "20",
                     "--out", str(tmp_path / "report"), "--log-level", "ERROR"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_FAULT
    assert err.strip().splitlines()[-1] == "fault: control: ValueError: edf broke"
    assert "Traceback" not in err
    report = (tmp_path / "report" / "report.json").read_text()
    assert '"fault": "control: ValueError: edf broke"' in report and '"kind": "fault"' in report
