"""Edges of the operator API on a real server with a simulating runtime: every error in the documented
shape and status (400 not JSON, 422 schema, 500 internal), strict numbers, deep YAML, one-box scenes."""

from __future__ import annotations

import httpx
import pytest

from app.bridge.server import BridgeServer

pytestmark = pytest.mark.wallclock

ERROR_KEYS = {"detail", "problems"}


def _is_error_shape(response: httpx.Response) -> bool:
    return response.headers["content-type"].startswith("application/json") and set(response.json()) == ERROR_KEYS


def test_randomise_makes_a_one_box_scene(api: httpx.Client, sim_runtime) -> None:
    response = api.post("/api/scene/randomise", json={"n_boxes": 1, "seed": 0})
    assert response.status_code == 200, response.text
    assert len(response.json()["boxes"]) == 1


@pytest.mark.parametrize(("content", "content_type"), [
    (b"{not json", "application/json"),
    (b"\xff\xfe\x00", "application/json"),
    (b'{"seed": 1}', "text/plain"),
    (b"seed=1", "application/x-www-form-urlencoded"),
])
def test_a_body_that_is_not_json_is_400(api: httpx.Client, sim_runtime, content: bytes, content_type: str) -> None:
    for method, path in [("POST", "/api/scene/randomise"), ("PUT", "/api/sequence"), ("POST", "/api/run/step"),
                         ("POST", "/api/sequence/validate")]:
        response = api.request(method, path, content=content, headers={"Content-Type": content_type})
        assert response.status_code == 400, (method, path, response.text)
        assert _is_error_shape(response)  # FastAPI itself answers bytes that are not UTF-8 ("error parsing")


@pytest.mark.parametrize("body", [{"seed": True}, {"seed": 1.0}, {"seed": "1"}, {"seed": 1, "n_boxes": True},
                                  {"seed": 1, "n_boxes": 2.0}])
def test_integer_fields_refuse_booleans_floats_and_strings(api: httpx.Client, sim_runtime, body: dict) -> None:
    response = api.post("/api/scene/randomise", json=body)
    assert response.status_code == 422 and _is_error_shape(response), response.text


@pytest.mark.parametrize(("path", "body"), [
    ("/api/scene/boxes", {"id": "b", "position": [1.0, 2.0, 0.3], "yaw": True}),
    ("/api/scene/boxes", {"id": "b", "position": [1.0, True, 0.3]}),
    ("/api/scene/boxes", {"id": "b", "position": [1.0, "2", 0.3]}),
    ("/api/run/config", {"speed": True}),
    ("/api/run/step", {"seconds": False}),
])
def test_number_fields_refuse_booleans_and_strings(api: httpx.Client, sim_runtime, path: str, body: dict) -> None:
    response = api.post(path, json=body)
    assert response.status_code == 422 and _is_error_shape(response), response.text


def test_yaml_nested_500_deep_is_a_clear_422(api: httpx.Client, sim_runtime) -> None:
    deep = "name: x\nsubtasks: " + "[" * 500 + "]" * 500 + "\n"
    validated = api.post("/api/sequence/validate", json={"yaml": deep})
    assert validated.status_code == 200 and validated.json()["valid"] is False
    assert "nested more than" in validated.json()["problems"][0]["message"]
    loaded = api.put("/api/sequence", json={"yaml": deep})
    assert loaded.status_code == 422 and "nested more than" in loaded.json()["problems"][0]["message"]
    assert api.get("/api/sequence").json()["subtasks"] > 0, "the loaded sequence stays"


def test_unknown_routes_and_methods_answer_in_the_error_shape(api: httpx.Client) -> None:
    for method, path, code in [("GET", "/api/nothing-here", 404), ("DELETE", "/api/run/start", 405)]:
        response = api.request(method, path)
        assert response.status_code == code and _is_error_shape(response), response.text


def test_an_unexpected_exception_is_a_500_in_the_error_shape(bridge: BridgeServer, api: httpx.Client, sim_runtime,
                                                            monkeypatch) -> None:
    """Fault injection: the runtime raises something nobody planned for; the client gets JSON, not text."""
    def broken() -> None:
        raise ZeroDivisionError("injected")

    monkeypatch.setattr(sim_runtime, "start", broken)
    response = api.post("/api/run/start")
    assert response.status_code == 500 and _is_error_shape(response), response.text
    assert "ZeroDivisionError" in response.json()["detail"] and "injected" not in response.text
    assert api.get("/api/health").status_code == 200, "the bridge keeps serving"
    schema = httpx.get(f"{bridge.url}/openapi.json").json()
    assert all("500" in op["responses"] for ops in schema["paths"].values() for op in ops.values())
