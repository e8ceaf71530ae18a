"""Record a run's snapshots to an MCAP file and read them back (replay, Foxglove, ROS 2 tools).

Crash safety: messages go into MCAP chunks (zstd, each self-contained with its schemas and channels
the first time they appear) that are closed, written and fsynced every `flush_every_s` of wall time
or when `chunk_bytes` of messages are pending, always between two snapshots, each time with the
summary and footer after them (`app.recording.rolling_summary`): a process killed at any moment leaves a file
that indexed MCAP readers open. `read_recording` reads it from the start without the summary section
(mcap's streaming reader), keeps every complete chunk and reports what it dropped: the at most
`flush_every_s` of snapshots still in memory at the kill, and a torn tail if the kill hit the write.
Topics: the project's own in `recording_topics` (JSON), Foxglove's in `foxglove_scene` (protobuf).

Writing happens on the recorder's own thread so that compression and fsync never hold up the loop
that publishes snapshots; a full queue makes the publisher wait (nothing is dropped silently).
"""

from __future__ import annotations

import json
import logging
import os
import queue
import struct
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Channel as McapChannel
from mcap.records import Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from app.recording import foxglove_scene
from app.recording.protobuf import ProtobufDecoder, boxes_message, depth_array, points_message
from app.recording.rolling_summary import RollingSummaryStream
from app.recording.topics import (
    FIXED_TOPICS,
    FORMAT,
    SCHEMAS,
    STATUS_TOPIC,
    depth_frame_from_messages,
    depth_messages,
    depth_topics,
    snapshot_from_messages,
    snapshot_messages,
)
from app.runtime.snapshot import Snapshot
from core.atomic_file import fsync_dir
from core.robot.model import RobotModel
from core.types import DepthFrame

log = logging.getLogger(__name__)

MCAP_MAGIC = b"\x89MCAP0\r\n"
GZIP_MAGIC = b"\x1f\x8b"
NEVER_SPLIT = 1 << 62
"""The mcap writer's own chunk limit, set out of reach: only the recorder closes chunks (between snapshots)."""
END_METADATA = "recording_end"
"""Metadata record written by `Recorder.close`: a file without it was interrupted (its summary may be whole)."""
_CLOSE = object()


class Recorder:
    """Subscriber that appends every snapshot to an MCAP recording (`runtime.subscribe(Recorder(path))`)."""

    def __init__(self, path: Path, points_every: int = 10, depth_frames: bool = False, flush_every_s: float = 1.0,
                 chunk_bytes: int = 1 << 20, queue_size: int = 64, sim_time: bool = False,
                 model_every_s: float = 2.0, robot: RobotModel | None = None) -> None:
        """`sim_time`: log times are the snapshots' simulation time (lockstep runs), else wall clock (live runs,
        whose simulation time stops while paused and restarts at Reset). `model_every_s`: the robot's meshes are
        written again after this much log time, so a reader that seeks without the index still draws it."""
        self.path = Path(path)
        self.sim_time = sim_time
        self.model_every_s = model_every_s
        self.robot = robot or RobotModel()
        foxglove_scene.robot_model(self.robot, 0.0)  # loads and converts the meshes once, before the run
        self._model_t: float | None = None
        self.points_every = max(1, points_every)
        self.depth_frames = depth_frames
        self.flush_every_s = flush_every_s
        self.chunk_bytes = chunk_bytes
        self.count = 0
        """Snapshots written (after `close`, all that were recorded)."""
        self.chunks = 0
        self.error: BaseException | None = None
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._stream = RollingSummaryStream(self._fd)
        self._writer = Writer(self._stream, chunk_size=NEVER_SPLIT,  # type: ignore[arg-type] (write, tell, flush)
                              compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="perceptive-htmpc-studio")
        self._writer.add_metadata("recording", {"format": FORMAT, "points_every": str(self.points_every),
                                                "depth_frames": str(depth_frames).lower(),
                                                "flush_every_s": str(flush_every_s),
                                                "log_time": "simulation" if sim_time else "wall clock"})
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._last_depth_t: dict[str, float] = {}
        self._pending_bytes = 0
        self._closed = False
        self._stream.commit(self._writer)
        fsync_dir(self.path.parent)
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size)
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)
        self._thread.start()

    def __call__(self, snap: Snapshot) -> None:
        while self._thread.is_alive():
            try:
                self._queue.put(snap, timeout=0.5)
                return
            except queue.Full:
                continue

    @property
    def writes(self) -> list[tuple[float, int]]:
        """(seconds, bytes) of each flush's one write of chunk, summary and footer (`RollingSummaryStream`)."""
        return self._stream.writes

    def close(self) -> None:
        """Write what is queued, the summary and the footer; the file is then a complete MCAP file."""
        if self._thread.is_alive():
            self._queue.put(_CLOSE)
            self._thread.join()
        if self._closed:
            return
        self._closed = True
        try:
            if self.error is None:
                self._writer.add_metadata(END_METADATA, {"snapshots": str(self.count)})
                self._stream.commit(self._writer)
        finally:
            os.close(self._fd)

    # --- the writer thread -------------------------------------------------------------------------

    def _run(self) -> None:
        last_flush = time.monotonic()
        try:
            while True:
                try:
                    item = self._queue.get(timeout=self.flush_every_s / 4)
                except queue.Empty:
                    item = None
                if item is _CLOSE:
                    return
                if item is not None:
                    self._write(item)
                due = time.monotonic() - last_flush >= self.flush_every_s
                if self._pending_bytes and (due or self._pending_bytes >= self.chunk_bytes):
                    self._flush()
                    last_flush = time.monotonic()
        except Exception as err:  # a full disk must not take the runtime down: log it, stop recording
            self.error = err
            log.exception("recording to %s failed; recording stopped", self.path)

    def _channel(self, topic: str, schema_name: str) -> int:
        if topic not in self._channels:
            if schema_name not in self._schemas:
                protobuf = foxglove_scene.SCHEMAS.get(schema_name)
                self._schemas[schema_name] = (
                    self._writer.register_schema(schema_name, "jsonschema", json.dumps(SCHEMAS[schema_name]).encode())
                    if protobuf is None else self._writer.register_schema(schema_name, "protobuf", protobuf.data))
            encoding = "protobuf" if schema_name in foxglove_scene.SCHEMAS else "json"
            self._channels[topic] = self._writer.register_channel(topic, encoding, self._schemas[schema_name])
        return self._channels[topic]

    def _encoded(self, snap: Snapshot) -> list[tuple[str, str, bytes]]:
        """(topic, schema, bytes) of one snapshot: Foxglove's channels first, `/run/status` last."""
        t = snap.state.t
        with_model = self._model_t is None or not 0.0 <= t - self._model_t < self.model_every_s
        if with_model:
            self._model_t = t
        stamp = None if self.sim_time else snap.wall_time
        scene = foxglove_scene.scene_messages(self.robot, snap, with_points=self.count % self.points_every == 0,
                                              with_model=with_model, t_s=stamp)
        out = [(topic, foxglove_scene.PROTOBUF_TOPICS[topic], data) for topic, data in scene]
        topics = dict(FIXED_TOPICS)
        json_messages = snapshot_messages(snap)
        if self.depth_frames:
            for frame in snap.depth_frames:
                if self._last_depth_t.get(frame.camera) != frame.t:
                    self._last_depth_t[frame.camera] = frame.t
                    out.append((foxglove_scene.depth_topic(frame.camera), "foxglove.RawImage",
                                foxglove_scene.depth_image(frame, stamp)))
                    json_messages[:0] = depth_messages(frame)
                    topics.update(depth_topics(frame.camera))
        out += [(topic, topics[topic], json.dumps(message, allow_nan=False, separators=(",", ":")).encode())
                for topic, message in json_messages]
        return out

    def _write(self, snap: Snapshot) -> None:
        log_time = int((snap.state.t if self.sim_time else snap.wall_time) * 1e9)
        for topic, schema_name, data in self._encoded(snap):
            self._writer.add_message(self._channel(topic, schema_name), log_time, data, log_time,
                                     sequence=self.count)
            self._pending_bytes += len(data)
        self.count += 1

    def _flush(self) -> None:
        self._stream.commit(self._writer)  # closes the chunk in progress, writes it with a summary, fsyncs
        self._pending_bytes = 0
        self.chunks += 1
        log.debug("recording %s: chunk %d written, %d snapshots", self.path, self.chunks, self.count)


# --- reading ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Recording(Sequence[Snapshot]):
    """The snapshots of a recording (a sequence of them) and what reading it found."""

    path: Path
    snapshots: tuple[Snapshot, ...]
    depth_frames: tuple[DepthFrame, ...] = ()
    metadata: dict[str, str] = field(default_factory=dict)
    closed: bool = True
    """The recorder was closed: the file ends with its summary and footer after the end-of-recording record."""
    file_bytes: int = 0
    read_bytes: int = 0
    """Bytes up to the end of the last complete record; the rest was dropped."""
    tail_error: str = ""

    @property
    def dropped_bytes(self) -> int:
        return self.file_bytes - self.read_bytes

    @property
    def report(self) -> str:
        """One line on what was read and, for an interrupted recording, what was dropped."""
        n = len(self.snapshots)
        span = f" ({self.snapshots[0].state.t:.2f}–{self.snapshots[-1].state.t:.2f} s)" if n else ""
        if self.closed:
            return f"{self.path.name}: {n} snapshots{span}, complete"
        tail = (f"dropped an unfinished chunk of {self.dropped_bytes} bytes ({self.tail_error})" if self.dropped_bytes
                else "the file ends with the summary of its last chunk (indexed readers open it as it is)")
        flush = self.metadata.get("flush_every_s", "?")
        return (f"{self.path.name}: {n} snapshots{span} read; the recording was interrupted (never closed): "
                f"{tail}; snapshots of the last {flush} s before it stopped were never written (dropped)")

    def __len__(self) -> int:
        return len(self.snapshots)

    def __getitem__(self, index: int) -> Snapshot:
        return self.snapshots[index]

    def __iter__(self) -> Iterator[Snapshot]:
        return iter(self.snapshots)


class _Assembler:
    """Collects messages by snapshot (MCAP sequence) and topic; a snapshot is whole with its status."""

    def __init__(self) -> None:
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, McapChannel] = {}
        self.pending: dict[int, dict[str, Any]] = {}
        self.snapshots: list[Snapshot] = []
        self.depth: list[DepthFrame] = []
        self.metadata: dict[str, str] = {}
        self.ended = False
        self.protobuf = ProtobufDecoder()

    def add(self, record) -> None:
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, McapChannel):
            self.channels[record.id] = record
        elif isinstance(record, Metadata) and record.name == "recording":
            self.metadata = dict(record.metadata)
        elif isinstance(record, Metadata) and record.name == END_METADATA:
            self.ended = True
        elif isinstance(record, Message) and self.metadata.get("format") == FORMAT:  # others: refused after reading
            channel = self.channels[record.channel_id]
            message = self._decode(channel, record.data)
            if message is None:
                return
            messages = self.pending.setdefault(record.sequence, {})
            messages[channel.topic] = message
            if channel.topic == STATUS_TOPIC:
                self._complete(self.pending.pop(record.sequence))

    def _decode(self, channel: McapChannel, data: bytes) -> Any:
        """A JSON message as it is; of the Foxglove ones, what a snapshot holds (boxes, clouds, depth)."""
        if channel.message_encoding == "json":
            return json.loads(data)
        topic = channel.topic
        if topic not in _READ_PROTOBUF and not topic.endswith("/depth"):
            return None  # drawn from the snapshot's other fields (transforms, model, map objects, paths)
        message = self.protobuf.decode(self.schemas[channel.schema_id], data)
        return depth_array(message) if topic.endswith("/depth") else _READ_PROTOBUF[topic](message)

    def _complete(self, messages: dict[str, Any]) -> None:
        self.snapshots.append(snapshot_from_messages(messages))
        for topic, image in messages.items():
            if topic.endswith("/depth") and topic.removesuffix("/depth") + "/info" in messages:
                self.depth.append(depth_frame_from_messages(image, messages[topic.removesuffix("/depth") + "/info"]))


_READ_PROTOBUF = {"/scene/boxes": boxes_message, "/map/points": points_message, "/camera/clouds": points_message}


def read_recording(path: Path) -> Recording:
    """Every whole snapshot of an MCAP recording, in order, read without its summary section.

    An interrupted recording (the process was killed) loads up to its last complete chunk; `report`
    says what was dropped. A file that is not a studio recording raises ValueError.
    """
    path = Path(path)
    with open(path, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
        if head[:2] == GZIP_MAGIC:
            raise ValueError(f"{path} is an old .jsonl.gz recording; this version reads MCAP recordings only "
                             "(record again with --record FILE.mcap)")
        if head != MCAP_MAGIC:
            raise ValueError(f"{path} is not a studio recording (expected an MCAP file)")
        f.seek(0)
        parts = _Assembler()
        footer, data_ended, read_bytes, tail_error = False, False, len(MCAP_MAGIC), ""
        records = StreamReader(f, emit_chunks=True, validate_crcs=True, record_size_limit=1 << 31).records
        while True:
            try:
                record = next(records)
                data_ended = data_ended or isinstance(record, DataEnd)
                if data_ended or isinstance(record, Message):  # the summary repeats what was read; messages
                    inner = []  # come in CRC-checked chunks (a torn tail can look like anything)
                else:
                    inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else [record]
            except StopIteration:
                break
            except (McapError, ValueError, struct.error, EOFError, OSError) as err:  # the unfinished tail
                tail_error = type(err).__name__ if not str(err) else f"{type(err).__name__}: {err}"
                break
            for item in inner:
                parts.add(item)
            footer = isinstance(record, Footer)
            read_bytes = f.tell()
        whole_file = footer and not tail_error
        if whole_file:
            read_bytes, tail_error = f.tell(), ""
        closed = whole_file and parts.ended
        file_bytes = os.fstat(f.fileno()).st_size
    found = parts.metadata.get("format", "")
    if found.startswith(FORMAT.rsplit("/", 1)[0]) and found != FORMAT:
        raise ValueError(f"{path} is a recording of an older version ({found}); this version reads {FORMAT} "
                         "(record the run again)")
    if found != FORMAT:
        raise ValueError(f"{path} is not a studio recording (expected format {FORMAT})")
    recording = Recording(path, tuple(parts.snapshots), tuple(parts.depth), parts.metadata, closed, file_bytes,
                          read_bytes, tail_error)
    if not closed:
        log.warning("%s", recording.report)
    return recording
