"""The live loops ask for a raised priority (app/thread_priority.py): they get it where the system allows, the main
thread (and so whatever it starts later) keeps its own, the mapping process runs `NICENESS` below the loops,
and without permission everything runs at normal priority."""

from __future__ import annotations

import logging
import os
import threading
import time

import pytest

import core.sim  # noqa: F401  (GL backend first)
from app import thread_priority
from app.runtime import Runtime, RuntimeConfig
from app.runtime.map_process import NICENESS


def _niceness(tid: int) -> int:
    return os.getpriority(os.PRIO_PROCESS, tid)


def _may_raise_priority() -> bool:
    result: list[bool] = []
    probe = threading.Thread(
        target=lambda: result.append(thread_priority.set_thread_niceness(thread_priority.thread_niceness() - 1)))
    probe.start()
    probe.join()
    return result[0]


@pytest.mark.wallclock
def test_live_loops_run_at_raised_priority_and_the_map_below_them() -> None:
    if not _may_raise_priority():
        pytest.skip("no permission to raise priority here (needs root or CAP_SYS_NICE)")
    main_before = thread_priority.thread_niceness()
    rt = Runtime(RuntimeConfig(live_niceness=-7))
    rt.start_live()
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and _niceness(rt.map.pid) != -7 + NICENESS:
            time.sleep(0.2)  # the worker sets its priority once started
        loops = [*rt.live.loops, rt.live.watchdog]
        assert {_niceness(loop._thread.native_id) for loop in loops} == {-7}
        assert thread_priority.thread_niceness() == main_before, "the main thread keeps its priority"
        assert _niceness(rt.map.pid) == -7 + NICENESS
    finally:
        rt.shutdown()


def test_without_permission_everything_runs_at_normal_priority(monkeypatch, caplog) -> None:
    def refuse(*_args) -> None:
        raise PermissionError("not permitted")

    monkeypatch.setattr(thread_priority, "_refused", False)
    monkeypatch.setattr(os, "setpriority", refuse)
    release = threading.Event()
    worker = threading.Thread(target=release.wait)  # a thread besides the main one, to be reniced
    worker.start()
    with caplog.at_level(logging.INFO, logger="app.thread_priority"):
        assert not thread_priority.boost_threads(thread_priority.thread_niceness() - 5)
        assert not thread_priority.set_thread_niceness(thread_priority.thread_niceness() - 5)
        assert thread_priority.set_thread_niceness(None) and thread_priority.boost_threads(None)
    release.set()
    worker.join()
    assert sum("no permission" in r.message for r in caplog.records) == 1, "said once"
