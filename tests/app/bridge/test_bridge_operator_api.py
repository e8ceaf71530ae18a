"""The operator API over real HTTP before a runtime is attached: sequence validation (errors name field
and line) works, the runtime's routes answer 503."""

from __future__ import annotations

import httpx
import pytest

from tests.app.bridge.conftest import BAD_SEQUENCE as BAD
from tests.app.bridge.conftest import EXAMPLE_SEQUENCE as EXAMPLE

pytestmark = pytest.mark.wallclock


def test_validate_accepts_an_example_sequence(api: httpx.Client) -> None:
    out = api.post("/api/sequence/validate", json={"yaml": EXAMPLE}).json()
    assert out == {"valid": True, "name": "two pick-up stops", "subtasks": 4, "problems": [], "warnings": []}


def test_validate_names_field_and_line(api: httpx.Client) -> None:
    out = api.post("/api/sequence/validate", json={"yaml": BAD}).json()
    assert out["valid"] is False
    assert [(p["field"], p["line"]) for p in out["problems"]] == [("subtasks.0.target.y", 5)]


def test_validate_reports_yaml_syntax_errors_with_their_line(api: httpx.Client) -> None:
    out = api.post("/api/sequence/validate", json={"yaml": "name: x\nsubtasks: [\n"}).json()
    assert out["valid"] is False and out["problems"][0]["line"] is not None
    assert "not valid YAML" in out["problems"][0]["message"]


def test_runtime_routes_answer_503_until_a_runtime_is_attached(api: httpx.Client) -> None:
    for method, path in [("GET", "/api/state"), ("GET", "/api/progress"), ("POST", "/api/run/start"),
                         ("PUT", "/api/sequence")]:
        response = api.request(method, path, json={"yaml": EXAMPLE})
        assert response.status_code == 503 and "no runtime" in response.json()["detail"]
