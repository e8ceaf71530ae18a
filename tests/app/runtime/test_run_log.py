"""The run log keeps a bounded window in memory and spills older rows to disk; reads cover the whole run."""

import gc
import math

import numpy as np

from app.runtime.run_log import RunLog
from core.types import Plan, PlanStatus, RobotState


def _plan(t: float, i: int) -> Plan:
    z = np.zeros((11, 9))
    return Plan(t=t, dt=0.3, q=z, v=z, u=z[:10], base_path=z[:, :3], ee_path=z[:, :3], task_errors=(0.1 * i, 0.2),
                solve_ms=(1.0, float(i % 7)), status=PlanStatus.OK if i % 5 else PlanStatus.FALLBACK)


def _fill(log: RunLog, n: int) -> None:
    for i in range(n):
        t = 0.1 * i
        q = np.full(9, float(i))
        q[:2] = 0.01 * i, 0.0
        state = RobotState(t, q, np.full(9, math.sin(i)))
        log.record(state, _plan(t, i) if i % 3 else None, 1.0 / (1 + i), i // 100, "running", i // 50,
                   np.full(9, 0.5), {"solve": float(i)})


def test_memory_holds_a_window_and_reads_cover_the_whole_run(tmp_path):
    bounded, full = RunLog(window_rows=100, spill_dir=tmp_path), RunLog(window_rows=10**6)
    _fill(bounded, 1000)
    _fill(full, 1000)
    assert len(bounded) == 1000 and bounded.rows_in_memory <= 125
    assert bounded.t == full.t
    np.testing.assert_array_equal(bounded.solve_ms, full.solve_ms)  # NaN where no plan
    np.testing.assert_array_equal(np.array(bounded.q), np.array(full.q))
    assert bounded.task_errors == full.task_errors and bounded.timings_ms == full.timings_ms
    assert bounded.summary() == full.summary()
    bounded.event(3.0, "fault", "why")
    assert bounded.to_json()["events"] == [{"t": 3.0, "kind": "fault", "detail": "why"}]
    assert bounded.summary()["faults"] == 1.0
    spill = list(tmp_path.iterdir())
    assert len(spill) == 1
    del bounded
    gc.collect()
    assert not spill[0].exists(), "the spill file outlived its log"
