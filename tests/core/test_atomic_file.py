"""Crash-safe saves: temp file in the same directory, fsync, rename, fsync of the directory; a process
killed (SIGKILL) in the middle of a save leaves the previous file whole."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from core import atomic_file
from core.atomic_file import atomic_output, write_bytes_atomic, write_text_atomic

ROOT = Path(__file__).parents[2]


def test_round_trip_and_no_temporary_left(tmp_path: Path) -> None:
    path = tmp_path / "scene.yaml"
    write_text_atomic(path, "a: 1\n")
    write_text_atomic(path, "a: 2\n")
    write_bytes_atomic(tmp_path / "blob", b"\x00\x01")
    assert path.read_text() == "a: 2\n"
    assert (tmp_path / "blob").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blob", "scene.yaml"]


def test_an_error_while_writing_keeps_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "report.json"
    path.write_text('{"old": true}')
    with pytest.raises(RuntimeError), atomic_output(path) as f:
        f.write('{"new": ')
        raise RuntimeError("encoder failed")
    assert json.loads(path.read_text()) == {"old": True}
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_protocol_is_write_fsync_rename_fsync_dir(tmp_path: Path, monkeypatch) -> None:
    """The order matters: the data is durable before the name points at it, and the rename is made durable."""
    calls: list[str] = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd: int) -> None:
        calls.append("fsync_dir" if os.path.isdir(f"/proc/self/fd/{fd}") else "fsync_file")
        real_fsync(fd)

    def replace(src, dst) -> None:
        assert Path(src).parent == Path(dst).parent, "the temporary file must be in the target's directory"
        calls.append("rename")
        real_replace(src, dst)

    monkeypatch.setattr(atomic_file.os, "fsync", fsync)
    monkeypatch.setattr(atomic_file.os, "replace", replace)
    write_text_atomic(tmp_path / "x.txt", "hello")
    assert calls == ["fsync_file", "rename", "fsync_dir"]


def test_permissions_and_exclusive_creation(tmp_path: Path) -> None:
    path = tmp_path / "token"
    write_text_atomic(path, "secret\n", permissions=0o600, exclusive=True)
    assert path.stat().st_mode & 0o777 == 0o600
    with pytest.raises(FileExistsError):
        write_text_atomic(path, "other\n", exclusive=True)
    assert path.read_text() == "secret\n"
    assert [p.name for p in tmp_path.iterdir()] == ["token"]


SLOW_SAVE = """
import sys, time
from core.atomic_file import atomic_output
with atomic_output(sys.argv[1]) as f:
    f.write('{"rows": [')
    for i in range(100000):
        f.write(f'{i}, ')
        f.flush()
        if i == 10:
            print("writing", flush=True)
        time.sleep(0.001)
    f.write('0]}')
"""


@pytest.mark.wallclock
def test_sigkill_in_the_middle_of_a_save_keeps_the_previous_file(tmp_path: Path) -> None:
    path = tmp_path / "run_log.json"
    path.write_text('{"rows": [1, 2, 3]}')
    proc = subprocess.Popen([sys.executable, "-c", SLOW_SAVE, str(path)], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "writing"
        time.sleep(0.2)
        temporaries = [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
        assert temporaries and temporaries[0].stat().st_size > 0, "the save writes beside the target"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert json.loads(path.read_text()) == {"rows": [1, 2, 3]}
