"""Keep the native heap from growing with every Reset (glibc only; elsewhere these do nothing).

Reset rebuilds every live thread. glibc gives threads their own malloc arenas (up to 8 per core) and keeps
freed memory in them: 40 Start/Stop/Reset cycles through the bridge grew the studio's resident memory from
584 to 1046 MB before it levelled off. With at most `ARENAS` arenas and the free memory handed back to the
system after each Reset it stays level (bench/soak.py, `api_rss_growth_mb_per_min`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging

log = logging.getLogger(__name__)

ARENAS = 2
M_ARENA_MAX = -8
"""mallopt parameter number (glibc malloc.h)."""


def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name) if name else None
    except OSError:
        return None
    return libc if libc is not None and hasattr(libc, "malloc_trim") and hasattr(libc, "mallopt") else None


_LIBC = _libc()


def limit_arenas(arenas: int = ARENAS) -> None:
    """At most `arenas` malloc arenas for threads created from now on."""
    if _LIBC is not None and not _LIBC.mallopt(M_ARENA_MAX, arenas):
        log.debug("mallopt(M_ARENA_MAX) refused")


def release_free_memory() -> None:
    """Hand the heap's free memory back to the system."""
    if _LIBC is not None:
        _LIBC.malloc_trim(0)
