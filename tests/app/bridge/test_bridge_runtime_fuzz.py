"""schemathesis with a real runtime attached (the embedded simulation, so every route can succeed):
at least 500 generated requests (`--schemathesis-full`: at least 2,000), no 5xx at all, every response
as documented."""

from __future__ import annotations

import pytest

from app.bridge.server import BridgeServer
from tests.app.bridge.test_bridge_openapi_fuzz import fuzz, fuzz_budget

pytestmark = pytest.mark.wallclock


@pytest.mark.slow
def test_fuzzing_a_simulating_runtime_finds_no_server_error(bridge: BridgeServer, sim_runtime,
                                                            pytestconfig: pytest.Config) -> None:
    examples, least = fuzz_budget(pytestconfig)
    statuses = fuzz(bridge, examples)
    print(f"\n{sum(statuses.values())} cases, by status: {dict(sorted(statuses.items()))}")
    assert sum(statuses.values()) >= least, statuses
    assert not any(code >= 500 for code in statuses), statuses
    assert sum(n for code, n in statuses.items() if 200 <= code < 300) >= 100, statuses
