"""schemathesis against the bridge's OpenAPI schema, served by real uvicorn: at least 500 generated
requests (valid and invalid; `--schemathesis-full`: at least 2,000), none answered with a 5xx, every
response as the schema documents it."""

from __future__ import annotations

from collections import Counter

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from schemathesis import GenerationMode
from schemathesis.checks import (
    content_type_conformance,
    ignored_auth,
    negative_data_rejection,
    not_a_server_error,
    response_schema_conformance,
    status_code_conformance,
)

from app.bridge.server import BridgeServer
from tests.app.bridge.conftest import auth

pytestmark = pytest.mark.wallclock

CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance,
          negative_data_rejection, ignored_auth]
MIN_CASES = 500
FULL_CASES = 2000
"""With `pytest --schemathesis-full`."""


def fuzz_budget(config: pytest.Config) -> tuple[int, int]:
    """(examples per operation and mode, least total cases) for this run."""
    return (100, FULL_CASES) if config.getoption("--schemathesis-full") else (25, MIN_CASES)


def fuzz(bridge: BridgeServer, examples_per_mode: int, checks: list = CHECKS) -> Counter:
    """Run every operation with `examples_per_mode` valid cases and, where it takes any input, as many invalid
    ones; count the responses by status."""
    schema = schemathesis.openapi.from_url(f"{bridge.url}/openapi.json")
    statuses: Counter = Counter()
    for result in schema.get_all_operations():
        operation = result.ok()
        inputs = [operation.path_parameters, operation.query, operation.headers, operation.body]
        modes = [GenerationMode.POSITIVE] + ([GenerationMode.NEGATIVE] if any(len(p) for p in inputs) else [])
        for mode in modes:
            @settings(max_examples=examples_per_mode, deadline=None, database=None, derandomize=True,
                      phases=[Phase.generate], suppress_health_check=list(HealthCheck))
            @given(case=operation.as_strategy(generation_mode=mode))
            def run(case) -> None:
                response = case.call(base_url=bridge.url, headers=auth(bridge.token))
                statuses[response.status_code] += 1
                case.validate_response(response, checks=checks, headers=auth(bridge.token))

            run()
    return statuses


@pytest.mark.slow
def test_fuzzing_before_a_runtime_is_attached_finds_only_the_documented_503(bridge: BridgeServer,
                                                                             pytestconfig: pytest.Config) -> None:
    """A bridge whose runtime is not attached yet answers the runtime's routes with 503, as documented."""
    examples, least = fuzz_budget(pytestconfig)
    statuses = fuzz(bridge, examples, [c for c in CHECKS if c is not not_a_server_error])
    print(f"\n{sum(statuses.values())} cases, by status: {dict(sorted(statuses.items()))}")
    assert sum(statuses.values()) >= least, statuses
    assert not any(code >= 500 and code != 503 for code in statuses), statuses
