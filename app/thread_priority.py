"""Scheduling priority for the threads that keep time (the live loops, the bridge's event loop, a driver).

Why: the live loops share one GIL. On a machine short of CPU, a thread preempted by another program while
it holds the GIL stalls every loop of the process: control steps that need 20 ms of CPU took 200 ms of
wall time beside two CPU burners (bench/closed_loop.py). Asking the kernel to run these threads first
(a lower niceness, as robot control stacks do) keeps them on time; ordinary programs get the rest.

Linux sets niceness per thread, and a new thread or child process inherits its creator's. So the threads
of this process are reniced one by one, except the main thread (whatever it starts later, such as a test
runner's subprocesses or a benchmark's CPU burners, stays at normal priority), and a loop thread started
later renices itself (`set_thread_niceness`). Lowering niceness needs root or CAP_SYS_NICE
(`sudo setcap cap_sys_nice+ep "$(readlink -f .venv/bin/python)"`); without it everything runs at
normal priority, as before, and the log says so once.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading

log = logging.getLogger(__name__)

_refused = False


def thread_niceness() -> int:
    """Niceness of the calling thread (Linux: per thread)."""
    return os.getpriority(os.PRIO_PROCESS, threading.get_native_id())


def set_thread_niceness(niceness: int | None) -> bool:
    """Renice the calling thread to `niceness` if that is higher priority than it has; whether it now has it
    (None: leave it, True)."""
    if niceness is None:
        return True
    return _renice(threading.get_native_id(), niceness)


def lower_thread_niceness(niceness: int) -> None:
    """Renice the calling thread to `niceness` (at most 19) if that is lower priority than it has: a thread that
    must not take time from the loops that keep it (lowering one's own priority needs no privilege)."""
    tid = threading.get_native_id()
    with contextlib.suppress(OSError):
        if os.getpriority(os.PRIO_PROCESS, tid) < niceness:
            os.setpriority(os.PRIO_PROCESS, tid, min(niceness, 19))


def boost_threads(niceness: int | None) -> bool:
    """Renice every thread of this process but the main one to `niceness` (where that raises its priority);
    whether all of them have it now."""
    if niceness is None:
        return True
    main = threading.main_thread().native_id
    try:
        tids = [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:  # not Linux: niceness is per process there, and the main thread's children would inherit it
        return False
    return all([_renice(tid, niceness) for tid in tids if tid != main])


def _renice(tid: int, niceness: int) -> bool:
    global _refused
    try:
        if os.getpriority(os.PRIO_PROCESS, tid) <= niceness:
            return True
        os.setpriority(os.PRIO_PROCESS, tid, niceness)
        return True
    except ProcessLookupError:  # the thread ended meanwhile
        return True
    except PermissionError:
        if not _refused:
            _refused = True
            log.info("no permission to raise the live loops' priority to niceness %d (needs root or "
                     "CAP_SYS_NICE): they run at normal priority", niceness)
        return False
