"""Auth: where the token comes from; every mutating route and the robot link refuse without it."""

from __future__ import annotations

import json
import stat
import subprocess
import sys
from pathlib import Path

import httpx
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from app.bridge.auth import TOKEN_ENV, masked, read_token, resolve_token
from app.bridge.server import BridgeServer
from tests.app.bridge.conftest import ROOT, auth

pytestmark = pytest.mark.wallclock


def _mutating_routes(bridge: BridgeServer) -> list[tuple[str, str]]:
    """Every operation of the OpenAPI schema that is not a GET."""
    paths = httpx.get(f"{bridge.url}/openapi.json").json()["paths"]
    return [(method.upper(), path.replace("{box_id}", "box_a")) for path, ops in paths.items() for method in ops
            if method != "get"]


def test_token_order_config_then_environment_then_file(tmp_path: Path) -> None:
    path = tmp_path / "token"
    path.write_text("from-the-file-0123456789\n")
    path.chmod(0o600)
    env = {TOKEN_ENV: "from-the-environment-0123"}
    assert resolve_token("from-the-config-012345678", path, env).value == "from-the-config-012345678"
    assert resolve_token(None, path, env).source == "environment"
    assert resolve_token(None, path, {}).value == "from-the-file-0123456789"


def test_first_run_generates_and_saves_a_token_and_prints_only_a_prefix(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "config" / "htmpc-studio" / "bridge_token"
    first = resolve_token(None, path, {})
    assert first.source == "generated" and len(first.value) >= 32
    out = capsys.readouterr().out
    assert first.value not in out and masked(first.value) in out and str(path) in out
    assert first.value not in repr(first) and first.value not in first.describe()
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    again = resolve_token(None, path, {})
    assert again.value == first.value and again.source == "file"
    assert read_token(path, {}) == first.value


@pytest.mark.parametrize("mode", [0o640, 0o604, 0o644, 0o660])
def test_a_token_file_others_may_read_is_refused(tmp_path: Path, mode: int) -> None:
    """Refused, not warned about: a warning would let a leaked token keep moving the robot."""
    path = tmp_path / "bridge_token"
    path.write_text("from-the-file-0123456789\n")
    path.chmod(mode)
    for read in (lambda: resolve_token(None, path, {}), lambda: read_token(path, {})):
        with pytest.raises(ValueError, match=f"readable by others.*chmod 600 {path}"):
            read()
    path.chmod(0o600)
    assert read_token(path, {}) == "from-the-file-0123456789"


def test_drivers_take_the_token_from_the_environment_or_a_file(tmp_path: Path) -> None:
    path = tmp_path / "bridge_token"
    assert read_token(path, {TOKEN_ENV: "from-the-environment-0123"}) == "from-the-environment-0123"
    with pytest.raises(ValueError, match="no bridge token"):
        read_token(path, {})


def test_the_sim_driver_refuses_a_token_on_its_command_line() -> None:
    """Every user can read a command line in `ps`; the driver says where the token goes instead."""
    proc = subprocess.run([sys.executable, "-m", "app.bridge.sim_driver", "--token", "a-token-on-the-command-line"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--token is refused" in proc.stderr and TOKEN_ENV in proc.stderr


def test_a_short_token_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="at least 16"):
        resolve_token("short", tmp_path / "token", {})


def test_every_mutating_route_refuses_without_the_token(bridge: BridgeServer) -> None:
    routes = _mutating_routes(bridge)
    assert {path for _, path in routes} >= {"/api/run/start", "/api/run/emergency-stop", "/api/sequence",
                                            "/api/scene/boxes", "/api/scene/boxes/box_a", "/api/scene/randomise"}
    wrong = [{}, auth("not-the-token-0123456789"), {"Authorization": f"Basic {bridge.token}"},
             {"Authorization": bridge.token}]
    with httpx.Client(base_url=bridge.url) as client:
        for method, path in routes:
            for headers in wrong:
                response = client.request(method, path, headers=headers, json={})
                assert response.status_code == 401, (method, path, headers, response.text)
                assert response.headers["www-authenticate"] == "Bearer"
            with_token = client.request(method, path, headers=auth(bridge.token), json={})
            assert with_token.status_code != 401, (method, path)


def test_read_only_routes_need_no_token(bridge: BridgeServer) -> None:
    response = httpx.get(f"{bridge.url}/api/health")
    assert response.status_code == 200 and response.json()["driver_connected"] is False
    assert httpx.get(f"{bridge.url}/openapi.json").status_code == 200


@pytest.mark.parametrize("headers", [{}, {"Authorization": "Bearer wrong-token-0123456789"}])
def test_robot_link_refuses_without_the_token(bridge: BridgeServer, headers: dict) -> None:
    with pytest.raises(InvalidStatus) as refused:
        connect(bridge.robot_url, additional_headers=headers, open_timeout=5)
    assert refused.value.response.status_code == 401
    assert not bridge.link.connected


def test_robot_link_accepts_the_token_and_one_driver_at_a_time(bridge: BridgeServer) -> None:
    with connect(bridge.robot_url, additional_headers=auth(bridge.token), open_timeout=5) as first:
        assert json.loads(first.recv(timeout=5))["type"] == "welcome"
        with pytest.raises(InvalidStatus) as refused:
            connect(bridge.robot_url, additional_headers=auth(bridge.token), open_timeout=5)
        assert refused.value.response.status_code == 409
        assert bridge.link.connected
