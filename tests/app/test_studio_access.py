"""The studio page is the operator's alone: a real studio refuses a WebSocket from another Origin (and that
socket cannot press Start, which the same client can with the studio's own Origin), refuses host names
other than this machine's (DNS rebinding), and in token mode serves nothing without the access link; the
real page still works in headless Chromium."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from urllib.parse import urlsplit

import httpx
import msgspec
import pytest
import viser
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from app.ui.studio import Studio
from core.scene import Scene
from tests.app.conftest import free_port

pytestmark = pytest.mark.wallclock

CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [0.0, 0.0, 3.0], "fov": 1.0,
          "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 800, "look_at": [0.0, 0.0, 0.0],
          "up_direction": [0.0, 0.0, 1.0]}
"""What a viser page sends first (viser counts a client as connected after it)."""


def _studio(require_token: bool) -> Iterator[tuple[Runtime, Studio]]:
    runtime = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene())
    studio = Studio(runtime, port=free_port(), require_token=require_token)
    yield runtime, studio
    studio.close()
    runtime.shutdown()


@pytest.fixture
def open_studio() -> Iterator[tuple[Runtime, Studio]]:
    yield from _studio(require_token=False)


@pytest.fixture
def token_studio() -> Iterator[tuple[Runtime, Studio]]:
    yield from _studio(require_token=True)


def _base(studio: Studio) -> str:
    return f"http://127.0.0.1:{studio.server.get_port()}"


def _socket(studio: Studio, headers: dict[str, str], host: str = "127.0.0.1") -> ClientConnection:
    """A raw viser client, as any script or page could open one; `host`: the name in its Host header."""
    port = studio.server.get_port()
    return connect(f"ws://{host}:{port}", sock=socket.create_connection(("127.0.0.1", port)), origin=None,
                   additional_headers=headers, subprotocols=[f"viser-v{viser.__version__}"], max_size=None,
                   open_timeout=10)


def _press_start(ws: ClientConnection, studio: Studio) -> None:
    ws.send(msgspec.msgpack.encode(CAMERA))
    ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": studio.run_panel.buttons._impl.uuid,
                                    "updates": {"value": "Start"}}))


def _wait_for(predicate, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not predicate():
        time.sleep(0.05)
    return predicate()


@pytest.mark.parametrize("headers", [{"Origin": "http://evil.example"}, {"Origin": "null"}, {},
                                     {"Origin": "http://127.0.0.1:1"}])
def test_a_socket_from_another_origin_is_refused_and_presses_nothing(open_studio, headers: dict) -> None:
    runtime, studio = open_studio
    with pytest.raises(InvalidStatus) as refused:
        _press_start(_socket(studio, headers), studio)
    assert refused.value.response.status_code == 403
    time.sleep(0.5)
    assert runtime.run_state == RunState.IDLE
    with _socket(studio, {"Origin": _base(studio)}) as own:  # the same client, the page's own Origin
        _press_start(own, studio)
        assert _wait_for(lambda: runtime.run_state == RunState.RUNNING), "the test client could not press Start"


def test_other_host_names_are_refused_without_a_token(open_studio) -> None:
    """DNS rebinding: evil.example re-pointed at 127.0.0.1 is same-origin with itself, so the Host decides."""
    runtime, studio = open_studio
    port = studio.server.get_port()
    with pytest.raises(InvalidStatus) as refused:
        _socket(studio, {"Origin": f"http://evil.example:{port}"}, host="evil.example")
    assert refused.value.response.status_code == 403
    assert httpx.get(_base(studio), headers={"Host": f"evil.example:{port}"}).status_code == 403
    with pytest.raises(InvalidStatus) as twice:  # two Origins: which one would a check believe?
        _socket(studio, [("Origin", _base(studio)), ("Origin", "http://evil.example")])
    assert twice.value.response.status_code == 403
    assert httpx.get(_base(studio)).status_code == 200
    assert httpx.get(f"http://localhost:{port}").status_code == 200


def test_token_mode_refuses_everything_without_the_link(token_studio) -> None:
    runtime, studio = token_studio
    base = _base(studio)
    assert studio.access.token and studio.url == f"http://127.0.0.1:{studio.server.get_port()}/?token=" \
                                                 f"{studio.access.token}"
    assert httpx.get(base).status_code == 401
    assert httpx.get(f"{base}/?token=not-the-token").status_code == 401
    with pytest.raises(InvalidStatus) as refused:
        _socket(studio, {"Origin": base})
    assert refused.value.response.status_code == 401
    link = httpx.get(studio.url)
    assert link.status_code == 303 and link.headers["location"] == "/"
    cookie = link.headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    name, value = cookie.split(";", 1)[0].split("=", 1)
    assert httpx.get(base, cookies={name: value}).status_code == 200
    with pytest.raises(InvalidStatus):  # the cookie does not make another Origin acceptable
        _socket(studio, {"Origin": "http://evil.example", "Cookie": f"{name}={value}"})
    with _socket(studio, {"Origin": base, "Cookie": f"{name}={value}"}) as ws:
        _press_start(ws, studio)
        assert _wait_for(lambda: runtime.run_state == RunState.RUNNING)


def test_listening_beyond_this_machine_always_needs_the_token() -> None:
    runtime = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene())
    studio = Studio(runtime, host="0.0.0.0", port=free_port())
    try:
        assert studio.access.token is not None
        assert httpx.get(f"http://127.0.0.1:{studio.server.get_port()}").status_code == 401
    finally:
        studio.close()
        runtime.shutdown()


def _page_works(page, url: str) -> None:
    page.goto(url)
    page.wait_for_selector("canvas", timeout=60_000)
    page.get_by_text("EMERGENCY STOP").first.wait_for(timeout=60_000)


@pytest.mark.slow
def test_the_real_page_works_in_chromium(open_studio, page) -> None:
    runtime, studio = open_studio
    _page_works(page, studio.url)
    page.get_by_role("button", name="Start").click()
    assert _wait_for(lambda: runtime.run_state == RunState.RUNNING, 30)


@pytest.mark.slow
def test_the_token_link_opens_the_page_in_chromium_and_leaves_the_address_bar(token_studio, page) -> None:
    runtime, studio = token_studio
    response = page.goto(_base(studio))
    assert response.status == 401 and "access link" in page.content()
    _page_works(page, studio.url)
    assert "token" not in urlsplit(page.url).query
    page.get_by_role("button", name="Start").click()
    assert _wait_for(lambda: runtime.run_state == RunState.RUNNING, 30)
