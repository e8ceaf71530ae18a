"""Crash-safe file writes: the file at `path` is always either the old one or the complete new one.

Protocol (POSIX): write a temporary file in the same directory, flush and fsync it, rename it over
`path` (atomic on one file system), then fsync the directory so the rename itself survives a power
loss. A process killed at any point (even SIGKILL) leaves the old file intact and, at worst, a
`.<name>.<random>.tmp` file beside it. Every save of the studio (scenes, sequences, reports, run logs,
benchmark results, figures) goes through here.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

TEMP_SUFFIX = ".tmp"


def fsync_dir(directory: str | os.PathLike) -> None:
    """fsync a directory, making renames and creations inside it durable (no-op where unsupported)."""
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, mode: str = "w", encoding: str | None = "utf-8",
                  permissions: int | None = None, exclusive: bool = False) -> Iterator[IO]:
    """Open a temporary file beside `path` for writing; on a clean exit it replaces `path` atomically.

    `mode` is "w" (text) or "wb"; `permissions` (e.g. 0o600) apply before any byte is written;
    `exclusive=True` refuses to replace an existing file (FileExistsError), as `O_EXCL` would.
    On an exception the temporary file is removed and `path` is untouched.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_output writes whole files: mode 'w' or 'wb', not {mode!r}")
    target = Path(path)
    directory = target.parent
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=TEMP_SUFFIX, dir=directory)
    try:
        if permissions is not None:
            os.fchmod(fd, permissions)
        with os.fdopen(fd, mode, encoding=None if "b" in mode else encoding) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        if exclusive:
            os.link(tmp_name, target)  # fails if `path` exists; the temporary name is removed below
            os.unlink(tmp_name)
        else:
            os.replace(tmp_name, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise
    fsync_dir(directory)


def write_text_atomic(path: str | os.PathLike, text: str, encoding: str = "utf-8", **kwargs) -> None:
    """Replace `path` with `text`, crash-safe (see the module docstring)."""
    with atomic_output(path, "w", encoding=encoding, **kwargs) as f:
        f.write(text)


def write_bytes_atomic(path: str | os.PathLike, data: bytes, **kwargs) -> None:
    """Replace `path` with `data`, crash-safe (see the module docstring)."""
    with atomic_output(path, "wb", **kwargs) as f:
        f.write(data)
