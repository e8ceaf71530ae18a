"""Serve the live run over Foxglove's WebSocket protocol (`python -m app --foxglove [PORT]`), beside the studio.

A runtime subscriber: each snapshot goes out on the same channels a recording has (`app.recording.foxglove_scene`
for the 3D panel, the project's JSON topics beside them), logged with the SDK on a context of its own, so
nothing else in the process reaches this server. Encoding happens on the server's own thread; a snapshot
that arrives while the previous one is still being encoded replaces the waiting one (a live view wants the
newest, never a backlog). The robot's meshes go out every `model_every_s`, so a client that connects late
draws the robot within that time.

Access: the server offers data only (no publishing, parameters or services). On this machine (127.0.0.1,
the default) any local client may watch, as with any Foxglove bridge; bound to another address it listens
behind `app.foxglove_access`, which refuses every connection without the access token (new every start),
as the studio does.
"""

from __future__ import annotations

import json
import logging
import threading

import foxglove

from app.recording import foxglove_scene
from app.recording.topics import FIXED_TOPICS, SCHEMAS, snapshot_messages
from app.runtime.snapshot import Snapshot
from core.robot.model import RobotModel

log = logging.getLogger(__name__)

DEFAULT_PORT = 8765


class FoxgloveLive:
    """Subscriber that serves snapshots to Foxglove clients; `close()` stops the server."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, robot: RobotModel | None = None,
                 model_every_s: float = 1.0, points_every: int = 5) -> None:
        self.robot = robot or RobotModel()
        self.model_every_s = model_every_s
        self.points_every = max(1, points_every)
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name="Perceptive HTMPC Studio", host=host, port=port,
                                            context=self.context)
        self.host, self.port = host, self.server.port
        self.count = 0
        self._channels: dict[str, foxglove.Channel] = {}
        self._model_wall: float | None = None
        self._depth_t: dict[str, float] = {}
        self._latest: Snapshot | None = None
        self._wake = threading.Condition()
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="foxglove-live", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def __call__(self, snap: Snapshot) -> None:
        with self._wake:
            self._latest = snap
            self._wake.notify()

    def close(self) -> None:
        with self._wake:
            self._stop = True
            self._wake.notify()
        self._thread.join(timeout=5.0)
        self.server.stop()

    def _run(self) -> None:
        while True:
            with self._wake:
                while self._latest is None and not self._stop:
                    self._wake.wait()
                snap, self._latest = self._latest, None
                if self._stop or snap is None:
                    return
            try:
                self._log(snap)
            except Exception:  # a view must never take the run down: log it and go on with the next snapshot
                log.exception("Foxglove live server: snapshot %d not sent", snap.seq)

    def _channel(self, topic: str, schema_name: str) -> foxglove.Channel:
        channel = self._channels.get(topic)
        if channel is None:
            protobuf = foxglove_scene.SCHEMAS.get(schema_name)
            channel = (foxglove.Channel(topic, schema=SCHEMAS[schema_name], context=self.context)
                       if protobuf is None else
                       foxglove.Channel(topic, schema=protobuf, message_encoding="protobuf", context=self.context))
            self._channels[topic] = channel
        return channel

    def _log(self, snap: Snapshot) -> None:
        log_time = int(snap.wall_time * 1e9)
        with_model = self._model_wall is None or not 0.0 <= snap.wall_time - self._model_wall < self.model_every_s
        if with_model:
            self._model_wall = snap.wall_time
        for topic, data in foxglove_scene.scene_messages(self.robot, snap, self.count % self.points_every == 0,
                                                         with_model, t_s=snap.wall_time):
            self._channel(topic, foxglove_scene.PROTOBUF_TOPICS[topic]).log(data, log_time=log_time)
        for frame in snap.depth_frames:
            if self._depth_t.get(frame.camera) == frame.t:
                continue
            self._depth_t[frame.camera] = frame.t
            self._channel(foxglove_scene.depth_topic(frame.camera), "foxglove.RawImage").log(
                foxglove_scene.depth_image(frame, snap.wall_time), log_time=log_time)
        for topic, message in snapshot_messages(snap):
            data = json.dumps(message, allow_nan=False, separators=(",", ":")).encode()
            self._channel(topic, FIXED_TOPICS[topic]).log(data, log_time=log_time)
        self.count += 1
