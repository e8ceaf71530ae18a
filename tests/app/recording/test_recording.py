"""MCAP recordings: read back by the `mcap` package's own reader, depth frames on request, and a recording
process killed with SIGKILL loads up to its unfinished tail and says what it dropped."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from app.recording import Recorder, read_recording
from app.recording.replay import ReplaySource
from app.recording.topics import SCHEMAS
from app.runtime import Runtime, RuntimeConfig
from core.sim.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence

ROOT = Path(__file__).parents[2]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, Recorder]:
    """A 3 s lockstep run with the object map, recorded with depth frames, small chunks."""
    path = tmp_path_factory.mktemp("rec") / "run.mcap"
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("a", (2.0, 0.5, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.5, y=-1.0))]))  # still driving at 3 s
    rec = Recorder(path, points_every=2, depth_frames=True, chunk_bytes=64 * 1024)
    rt.subscribe(rec)
    rt.run_lockstep(3.0, publish_every=1)
    rec.close()
    return path, rec


def test_the_mcap_package_reads_a_recording(recorded) -> None:
    path, rec = recorded
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = Counter()
        objects_seen, commands = 0, []
        for schema, channel, message in reader.iter_messages():
            body = json.loads(message.data)
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            assert json.loads(schema.data)["type"] == "object" and schema.name in SCHEMAS
            topics[channel.topic] += 1
            if channel.topic == "/map/objects":
                for obj in body["objects"]:
                    assert 0.0 <= obj["consistency"] <= 1.0 and len(obj["pose"]) == 4
                    objects_seen += 1
            if channel.topic == "/robot/command":
                commands.append(body["qdot"])
    assert summary.statistics.message_count == sum(topics.values())
    assert summary.statistics.chunk_count in (rec.chunks, rec.chunks + 1) and rec.chunks > 3  # +1: closed by close()
    assert topics["/run/status"] == topics["/robot/state"] == rec.count > 20
    assert topics["/plan"] > 20 and topics["/scene/boxes"] == rec.count and objects_seen > 0
    assert topics["/map/points"] == (rec.count + 1) // 2
    assert np.abs(np.array(commands)).max() > 0.05, "the run commanded motion"
    assert topics["/camera/hand/depth"] == topics["/camera/hand/info"] > 10


def test_read_recording_rebuilds_snapshots_and_depth_frames(recorded) -> None:
    path, rec = recorded
    recording = read_recording(path)
    assert recording.closed and recording.dropped_bytes == 0 and "complete" in recording.report
    assert len(recording) == rec.count and recording.metadata["format"].startswith("perceptive-htmpc-recording")
    last = recording[-1]
    assert last.plan is not None and last.plan.q.shape[1] == 9 and last.command.shape == (9,)
    assert last.object_map is not None and last.boxes[0].id == "a" and last.progress
    assert [s.state.t for s in recording] == sorted(s.state.t for s in recording)
    frame = recording.depth_frames[-1]
    assert frame.depth.dtype == np.float32 and frame.depth.shape == (240, 320)
    assert frame.K.shape == (3, 3) and frame.K[2, 2] == 1.0 and frame.T_world_camera.shape == (4, 4)
    assert np.isfinite(frame.depth).all() and frame.depth.max() > 0.0


def test_a_cut_file_loads_its_complete_chunks(recorded, tmp_path) -> None:
    """Power loss or a partial write: whatever byte the file ends at, every complete chunk is read."""
    path, _ = recorded
    data = path.read_bytes()
    full = read_recording(path)
    counts = []
    for fraction in (0.1, 0.37, 0.5, 0.81, 0.97):
        cut = tmp_path / f"cut{fraction}.mcap"
        cut.write_bytes(data[: int(len(data) * fraction)])
        part = read_recording(cut)
        assert not part.closed and part.dropped_bytes > 0 and "interrupted" in part.report
        assert part.read_bytes + part.dropped_bytes == part.file_bytes
        assert [s.seq for s in part] == [s.seq for s in full][: len(part)]
        counts.append(len(part))
    assert counts == sorted(counts) and counts[-1] > counts[0] > 0


SEQUENCE = ROOT / "tasks" / "examples" / "navigation_through_boxes.yaml"


def _wait_for_growth(path: Path, proc: subprocess.Popen, flushes: int, timeout_s: float = 240.0) -> int:
    """Wait until the recording's file has grown `flushes` times (one chunk written each); returns its size."""
    sizes = [0]
    deadline = time.monotonic() + timeout_s
    while len(sizes) <= flushes and time.monotonic() < deadline and proc.poll() is None:
        size = path.stat().st_size if path.exists() else 0
        if size != sizes[-1]:
            sizes.append(size)
        time.sleep(0.02)
    assert len(sizes) > flushes, f"the recording did not grow {flushes} times: {sizes}"
    return sizes[-1]


@pytest.mark.slow
def test_sigkill_while_recording_loses_only_the_unfinished_tail(tmp_path) -> None:
    """`python -m app run --headless --record` killed with SIGKILL mid-run: the file replays up to its tail."""
    path = tmp_path / "killed.mcap"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "app", "run", "--headless", "--sequence", str(SEQUENCE),
                             "--max-duration", "300", "--out", str(tmp_path / "report"), "--record", str(path)],
                            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        size_seen = _wait_for_growth(path, proc, flushes=4)
        shutil.copyfile(path, tmp_path / "before_kill.mcap")
        time.sleep(0.3)  # kill somewhere in the next second of recording
        proc.send_signal(signal.SIGKILL)
        assert proc.wait(timeout=30) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
    before = read_recording(tmp_path / "before_kill.mcap")
    after = read_recording(path)
    assert path.stat().st_size >= size_seen
    assert not after.closed and "interrupted" in after.report and "dropped" in after.report
    assert after.read_bytes + after.dropped_bytes == after.file_bytes
    assert len(after) >= len(before) > 5, (len(before), len(after))
    assert [s.seq for s in after][: len(before)] == [s.seq for s in before]
    assert after[-1].state.t > after[0].state.t and after[-1].plan is not None
    source = ReplaySource(path)  # what `python -m app replay FILE` loads
    assert len(source.snapshots) == len(after) and "interrupted" in source.recording.report
    print(f"\nkill test: {len(after)} snapshots ({after[0].state.t:.1f}–{after[-1].state.t:.1f} s sim) loaded, "
          f"{after.dropped_bytes} of {after.file_bytes} bytes dropped; {len(before)} were on disk "
          f"{0.3:.1f} s before the kill")


def test_problems_and_moved_goals_survive_the_recording(recorded) -> None:
    """What the studio shows beside the plan (the problems panel, a goal the planner moved, time left)
    comes back from a recording as it was published."""
    from dataclasses import replace

    from app.recording.topics import snapshot_from_messages, snapshot_messages
    from app.runtime.problems import ProblemKind, ProblemLog
    from tasks.sequencer import GoalShift

    snap = read_recording(recorded[0])[-1]
    problems = ProblemLog()
    problems.record(ProblemKind.QP_FAILURE, 1.5, "level 1 QP failed (1)")
    problems.record(ProblemKind.QP_FAILURE, 2.5, "level 2 QP failed (1)")
    moved = replace(snap.progress[0], goal_shift=GoalShift((1.0, 0.0), (1.05, 0.1)), timeout_s=30.0)
    snap = replace(snap, problems=problems.counts(), progress=(moved,))
    back = snapshot_from_messages(dict(json.loads(json.dumps(snapshot_messages(snap, with_points=False)))))
    assert back.problems == snap.problems and back.problems[0].count == 2
    assert back.progress[0].goal_shift == GoalShift((1.0, 0.0), (1.05, 0.1))
    assert back.progress[0].timeout_s == 30.0
