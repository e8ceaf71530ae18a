"""MCAP recordings: every message decodes with the schema the file carries (Foxglove's protobuf channels with
mcap-protobuf-support's decoder, the project's JSON ones against their JSON schema), log times are simulation
time, depth frames on request, and a recording process killed with SIGKILL opens in the `mcap` package's
indexed reader, loads up to its unfinished tail and says what it dropped."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_protobuf.decoder import DecoderFactory

from app.recording import Recorder, read_recording
from app.recording.foxglove_scene import PROTOBUF_TOPICS
from app.recording.repair import repair
from app.recording.replay import ReplaySource
from app.recording.topics import SCHEMAS
from app.runtime import Runtime, RuntimeConfig
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence

ROOT = Path(__file__).parents[3]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, Recorder]:
    """A 3 s lockstep run with the object map, recorded with depth frames, small chunks."""
    path = tmp_path_factory.mktemp("rec") / "run.mcap"
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("a", (2.0, 0.5, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=3.5, y=-1.0))]))  # still driving at 3 s
    rec = Recorder(path, points_every=2, depth_frames=True, chunk_bytes=64 * 1024, sim_time=True, model_every_s=1.0)
    rt.subscribe(rec)
    rt.run_lockstep(3.0, publish_every=1)
    rec.close()
    return path, rec


def _decoded(path: Path) -> list[tuple[str, str, object, int]]:
    """(topic, schema name, decoded message, log time) of every message, each decoded with the schema the file
    carries: protobuf by mcap-protobuf-support's decoder, JSON validated against its JSON schema."""
    protobuf = DecoderFactory()
    out = []
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema is not None
            if channel.message_encoding == "protobuf":
                assert schema.encoding == "protobuf" and PROTOBUF_TOPICS.get(channel.topic, schema.name) == schema.name
                decoder = protobuf.decoder_for("protobuf", schema)
                assert decoder is not None
                body = decoder(message.data)
            else:
                assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
                assert schema.name in SCHEMAS
                body = json.loads(message.data)
                jsonschema.validate(body, json.loads(schema.data))
            out.append((channel.topic, schema.name, body, message.log_time))
    return out


def test_every_message_decodes_with_the_schema_in_the_file(recorded) -> None:
    path, rec = recorded
    messages = _decoded(path)
    topics = Counter(topic for topic, *_ in messages)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(messages)
    assert summary.statistics.chunk_count in (rec.chunks, rec.chunks + 1) and rec.chunks > 3  # +1: closed by close()
    assert len(rec.writes) == rec.chunks + 2 and all(b > 0 for _, b in rec.writes)  # + the header's and close()'s
    assert topics["/run/status"] == topics["/robot/state"] == topics["/tf"] == rec.count > 20
    assert topics["/plan"] > 20 and topics["/scene/boxes"] == topics["/plan/paths"] == rec.count
    assert topics["/map/points"] == (rec.count + 1) // 2 and topics["/camera/clouds"] >= topics["/map/points"] - 1
    assert topics["/camera/hand/depth"] == topics["/camera/hand/info"] > 10
    assert topics["/robot/model"] >= 3, "the robot's meshes are sent again every simulated second"
    commands = [body["qdot"] for topic, _, body, _ in messages if topic == "/robot/command"]
    assert np.abs(np.array(commands)).max() > 0.05, "the run commanded motion"
    posterior = [o for topic, _, body, _ in messages if topic == "/map/posterior" for o in body["objects"]]
    assert posterior and all(0.0 <= o["consistency"] <= 1.0 and len(o["pose"]) == 4 for o in posterior)


def test_log_times_are_simulation_time(recorded) -> None:
    """A lockstep run plays in Foxglove at its simulated pace: each message's log time is its snapshot's t."""
    path, _ = recorded
    messages = _decoded(path)
    status = [(body["t"], log_time) for topic, _, body, log_time in messages if topic == "/run/status"]
    assert status[-1][0] > 2.5
    assert all(log_time == int(t * 1e9) for t, log_time in status)
    stamps = [(body.transforms[0].timestamp, log_time) for topic, _, body, log_time in messages  # type: ignore[attr-defined]
              if topic == "/tf"]
    assert all(abs(s.seconds * 10**9 + s.nanos - log_time) <= 1 for s, log_time in stamps), "stamped as logged"


def test_the_3d_channels_draw_the_robot_boxes_objects_and_paths(recorded) -> None:
    """What Foxglove's 3D panel needs: transforms from world through base to every link, the robot's meshes
    embedded in those link frames, boxes, mapped objects labelled with E[v], plans and targets."""
    path, _ = recorded
    last: dict[str, object] = {}
    for topic, _, body, _ in _decoded(path):
        last[topic] = body
    tf: object = last["/tf"]
    parents = {t.child_frame_id: t.parent_frame_id for t in tf.transforms}  # type: ignore[attr-defined]
    assert parents["base"] == "world" and parents["wrist_3_link"] == "base" and parents["camera_hand"] == "base"
    model = last["/robot/model"]
    meshes = {e.frame_id: e.models[0] for e in model.entities if e.models}  # type: ignore[attr-defined]
    assert set(meshes) == {"base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                           "wrist_2_link", "wrist_3_link"}
    assert all(m.media_type == "model/gltf-binary" and m.data[:4] == b"glTF" for m in meshes.values())
    boxes = last["/scene/boxes"].entities  # type: ignore[attr-defined]
    assert [e.id for e in boxes] == ["box/a"] and boxes[0].cubes[0].size.x == pytest.approx(0.6)
    objects = last["/map/objects"].entities  # type: ignore[attr-defined]
    # labelled as the studio labels them: '#4 E[v]=0.93'
    assert objects and all(e.texts[0].text.split(" E[v]=")[0] == "#" + e.id.removeprefix("object/") for e in objects)
    paths = {e.id for e in last["/plan/paths"].entities}  # type: ignore[attr-defined]
    assert {"plan/predicted_base", "plan/predicted_ee", "plan/planned_base"} <= paths
    assert any(p.startswith("target/0/") for p in paths)
    cloud = last["/map/points"]
    assert cloud.point_stride == 12 and len(cloud.data) > 12 * 100  # type: ignore[attr-defined]


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


@pytest.mark.wallclock
@pytest.mark.slow
def test_sigkill_while_recording_loses_only_the_unfinished_tail(tmp_path) -> None:
    """`python -m app run --headless --record` killed with SIGKILL mid-run: the file replays up to its tail."""
    path = tmp_path / "killed.mcap"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "app", "run", "--headless", "--sequence", str(SEQUENCE),
                             "--max-duration", "300", "--out", str(tmp_path / "report"), "--record", str(path)],
                            cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        size_seen = _wait_for_growth(path, proc, flushes=6)  # 4 held only 4-5 snapshots at load 20-30
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
    if after.dropped_bytes:  # the kill tore the one write of a flush (a millisecond a second): repair it
        print(f"\n{repair(path)}")
    with open(path, "rb") as f:  # the mcap package's indexed reader opens the killed file as it is
        indexed = sum(channel.topic == "/run/status" for _, channel, _ in make_reader(f).iter_messages())
    assert indexed >= len(before)
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
    back = snapshot_from_messages(dict(json.loads(json.dumps(snapshot_messages(snap)))))
    assert back.problems == snap.problems and back.problems[0].count == 2
    assert back.progress[0].goal_shift == GoalShift((1.0, 0.0), (1.05, 0.1))
    assert back.progress[0].timeout_s == 30.0


def test_a_torn_tail_is_repaired_for_indexed_readers(recorded, tmp_path, capsys) -> None:
    """A file cut inside a write has no footer: `python -m app recording repair FILE` copies every complete
    chunk under a new summary, and the mcap package's indexed reader and the replay then read the same
    snapshots."""
    from app.cli import main

    path, _ = recorded
    cut = tmp_path / "torn.mcap"
    cut.write_bytes(path.read_bytes()[: int(path.stat().st_size * 0.6)])
    with open(cut, "rb") as f, pytest.raises(McapError):
        list(make_reader(f).iter_messages())
    streamed = read_recording(cut)
    assert main(["recording", "repair", str(cut)]) == 0
    line = capsys.readouterr().out
    assert "repaired" in line and "unreadable tail dropped" in line
    with open(cut, "rb") as f:
        statuses = sum(channel.topic == "/run/status" for _, channel, _ in make_reader(f).iter_messages())
    again = read_recording(cut)
    assert statuses == len(streamed) == len(again) > 5
    assert [s.seq for s in again] == [s.seq for s in streamed]
    assert "nothing to repair" in repair(cut)
    other = tmp_path / "notes.mcap"
    other.write_text("not a recording")
    assert main(["recording", "repair", str(other)]) == 2 and "not an MCAP file" in capsys.readouterr().err
    assert other.read_text() == "not a recording"


def test_an_older_recording_is_refused_with_a_message(tmp_path) -> None:
    path = tmp_path / "old.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start()
        writer.add_metadata("recording", {"format": "perceptive-htmpc-recording/2"})
        writer.finish()
    with pytest.raises(ValueError, match="older version.*record the run again"):
        read_recording(path)


LAYOUT = ROOT / "docs" / "foxglove_layout.json"
LOCALIZATION_TOPIC = "/localization/health"


def layout_paths(layout: dict) -> list[str]:
    """Every message path the layout's plots and tables read."""
    panels = layout["configById"]
    paths = [p["value"] for key, panel in panels.items() if key.startswith("Plot!") for p in panel["paths"]]
    return paths + [panel["topicPath"] for key, panel in panels.items() if "topicPath" in panel]


def _resolve(message: object, fields: str) -> list:
    """The values a Foxglove message path's fields (`.a.b[0]`, `.objects[:].consistency`) name in a JSON message."""
    values = [message]
    for name, index in re.findall(r"\.(\w+)|\[([^\]]*)\]", fields):
        if name:
            values = [v[name] for v in values]
        elif index == ":":
            values = [item for v in values for item in v]
        else:
            values = [v[int(index)] for v in values]
    return values


def test_the_foxglove_layout_shows_what_a_recording_holds(recorded) -> None:
    """docs/foxglove_layout.json: a 3D panel of the recording's scene topics, plots of E[v] and solve times and
    the problems table; every topic it names is recorded and every field path resolves to values."""
    layout = json.loads(LAYOUT.read_text())
    panels = layout["configById"]

    def leaves(node) -> list[str]:
        return [node] if isinstance(node, str) else [*leaves(node["first"]), *leaves(node["second"])]

    assert sorted(leaves(layout["layout"])) == sorted(panels)
    last: dict[str, object] = {}
    for topic, _, body, _ in _decoded(recorded[0]):
        last[topic] = body
    scene = panels["3D!run"]["topics"]
    assert {"/robot/model", "/scene/boxes", "/map/objects", "/plan/paths", "/map/points"} <= set(scene) <= set(last)
    assert panels["3D!run"]["followTf"] == "base"
    paths = layout_paths(layout)
    assert "/map/posterior.objects[:].consistency" in paths and "/run/status.problems" in paths
    for path in paths:
        if path.startswith(LOCALIZATION_TOPIC + "."):  # recorded with localization only: test_base_frames.py
            continue
        topic = max((t for t in last if path == t or path.startswith(t + ".")), key=len)
        values = _resolve(last[topic], path[len(topic):])
        assert values and all(v is not None for v in values), path


def test_the_readme_names_every_topic_a_recording_holds(recorded) -> None:
    """README's topic list is complete: every topic of a recording (with depth frames) is named there."""
    readme = (ROOT / "README.md").read_text()
    topics = {re.sub(r"^/camera/[^/]+/", "/camera/<name>/", topic) for topic, *_ in _decoded(recorded[0])}
    assert "/camera/<name>/depth" in topics
    assert sorted(t for t in topics if f"`{t}`" not in readme) == []
