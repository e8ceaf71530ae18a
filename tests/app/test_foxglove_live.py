"""The live run over Foxglove's WebSocket protocol: a plain WebSocket client (the `websockets` package)
subscribes like Foxglove does and gets the robot's transforms and a scene update within a second, decodable
with the schemas the server advertises; bound for a real robot, the server needs its access token."""

from __future__ import annotations

import asyncio
import base64
import json
import struct
import time

import pytest
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory
from websockets.asyncio.client import connect
from websockets.exceptions import InvalidStatus

from app.foxglove_access import SUBPROTOCOL, serve_foxglove
from app.foxglove_live import FoxgloveLive
from app.runtime import Runtime, RuntimeConfig
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.conftest import free_port, start_studio, stop, studio_output

pytestmark = pytest.mark.wallclock

WANTED = ("/tf", "/scene/boxes", "/robot/model")


async def _first_messages(url: str, topics: tuple[str, ...], timeout_s: float) -> tuple[dict[str, object], float]:
    """Subscribe to `topics` as a Foxglove client does; the first decoded message of each, and the seconds from
    the subscription until all had arrived. `timeout_s` bounds the whole exchange, not each message: a server that
    keeps sending other messages fails the test with what it did send, instead of holding it."""
    decoders = DecoderFactory()
    deadline = time.monotonic() + timeout_s
    channels: dict[int, dict] = {}
    got: dict[str, object] = {}

    async def receive(ws):
        remaining = deadline - time.monotonic()
        try:
            return await asyncio.wait_for(ws.recv(), max(remaining, 0.0))
        except TimeoutError:
            advertised = sorted(c["topic"] for c in channels.values())
            raise AssertionError(f"after {timeout_s} s: advertised {advertised}, received {sorted(got)}, "
                                 f"wanted {list(topics)}") from None

    async with connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:  # type: ignore[list-item]
        while not all(any(c["topic"] == t for c in channels.values()) for t in topics):
            message = json.loads(await receive(ws))
            if message["op"] == "serverInfo":
                assert message["capabilities"] == [], "data only: no publishing, parameters or services"
            if message["op"] == "advertise":
                channels.update({c["id"]: c for c in message["channels"]})
        by_topic = {c["topic"]: c for c in channels.values()}
        subscriptions = {i: by_topic[t] for i, t in enumerate(topics, start=1)}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": c["id"]} for i, c in subscriptions.items()]}))
        subscribed = time.monotonic()
        while len(got) < len(topics):
            frame = await receive(ws)
            if isinstance(frame, str) or frame[0] != 0x01:  # 0x01: message data
                continue
            subscription, _log_time = struct.unpack_from("<IQ", frame, 1)
            channel = subscriptions[subscription]
            payload = bytes(frame[13:])
            if channel["encoding"] == "json":
                got.setdefault(channel["topic"], json.loads(payload))
                continue
            schema = Schema(id=channel["id"], name=channel["schemaName"], encoding=channel["schemaEncoding"],
                            data=base64.b64decode(channel["schema"]))  # binary schemas arrive base64-encoded
            decoder = decoders.decoder_for(channel["encoding"], schema)
            assert decoder is not None
            got.setdefault(channel["topic"], decoder(payload))
        return got, time.monotonic() - subscribed


@pytest.fixture(scope="module")
def live_run():
    rt = Runtime(RuntimeConfig(map_kind="ground_truth", publish_hz=20.0), scene=Scene((Box("a", (2.0, 1.0, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=1.5, y=-0.5))]))
    live = FoxgloveLive(port=free_port(), model_every_s=0.5)
    rt.subscribe(live)
    rt.start_live()
    try:
        rt.start()
        yield rt, live
    finally:
        rt.shutdown()
        live.close()


def test_a_websocket_client_gets_transforms_and_the_scene_within_a_second(live_run) -> None:
    _, live = live_run
    got, seconds = asyncio.run(_first_messages(live.url, WANTED, timeout_s=30.0))
    print(f"\nfirst /tf, /scene/boxes and /robot/model {seconds * 1000:.0f} ms after subscribing")
    assert seconds < 1.0
    frames = {t.child_frame_id: t.parent_frame_id for t in got["/tf"].transforms}  # type: ignore[attr-defined]
    assert frames["base"] == "world" and frames["forearm_link"] == "base"
    assert frames["base_true"] == "world" and "base_estimated" not in frames  # simulated, no localization
    assert [e.id for e in got["/scene/boxes"].entities] == ["box/a"]  # type: ignore[attr-defined]
    assert len([e for e in got["/robot/model"].entities if e.models]) == 7  # type: ignore[attr-defined]


def test_the_project_topics_are_served_beside_them(live_run) -> None:
    _, live = live_run
    got, _ = asyncio.run(_first_messages(live.url, ("/run/status", "/sequence/progress"), timeout_s=30.0))
    assert got["/run/status"]["run_state"] in ("running", "finished")  # type: ignore[index]


def test_a_server_for_a_real_robot_needs_its_access_token() -> None:
    """With a token required (a real robot, or any address beyond this machine) the handshake is refused
    without it; the printed URL carries it."""
    rt = Runtime(RuntimeConfig(map_kind="ground_truth", publish_hz=20.0), scene=Scene(),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=1.0, y=0.0))]))
    live = serve_foxglove("127.0.0.1", free_port(), require_token=True)
    rt.subscribe(live)
    rt.start_live()
    try:
        assert "?token=" in live.url
        bare = live.url.split("?")[0]
        with pytest.raises(InvalidStatus, match="401"):
            asyncio.run(_first_messages(bare, ("/tf",), timeout_s=10.0))
        with pytest.raises(InvalidStatus, match="401"):
            asyncio.run(_first_messages(bare + "?token=wrong", ("/tf",), timeout_s=10.0))
        got, _ = asyncio.run(_first_messages(live.url, ("/tf", "/scene/boxes"), timeout_s=30.0))
        assert "/tf" in got
    finally:
        rt.shutdown()
        live.close()


@pytest.mark.slow
def test_the_command_line_serves_foxglove_beside_the_studio() -> None:
    """`python -m app --foxglove PORT`: the studio and the Foxglove server of the same live run."""
    port = free_port()
    proc, url = start_studio("--foxglove", str(port))
    try:
        assert url.startswith("http://127.0.0.1:")
        try:
            got, seconds = asyncio.run(_first_messages(f"ws://127.0.0.1:{port}", ("/tf", "/scene/boxes"),
                                                       timeout_s=60.0))
        except AssertionError as err:
            raise AssertionError(f"{err}\nthe studio printed:\n{studio_output(proc)}") from None
        assert seconds < 1.0 and got["/scene/boxes"].entities  # type: ignore[attr-defined]
    finally:
        stop(proc)
