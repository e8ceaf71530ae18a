"""Shared fixtures: one robot model per session (building it parses the URDF)."""

from __future__ import annotations

from pathlib import Path

import pytest

from core.robot import RobotModel


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--schemathesis-full", action="store_true",
                     help="fuzz the bridge's operator API with at least 2,000 cases (default: at least 500)")


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return RobotModel()


SLOWEST = Path(__file__).with_name("slowest_tests.txt")


def _measured_s() -> dict[str, float]:
    """Seconds of the slowest tests as last measured (`slowest_tests.txt`; empty if it is missing)."""
    if not SLOWEST.exists():
        return {}
    rows = (line.split(maxsplit=1) for line in SLOWEST.read_text().splitlines() if line and not line.startswith("#"))
    return {node.strip(): float(seconds) for seconds, node in rows}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """With the tests spread over processes (scripts/test.sh: `-n`), the slowest go first, slowest first, so that
    a long closed loop is not started last while the other processes stand idle (longest-first scheduling); the
    rest keep their order. A run in one process keeps pytest's order (modules together: the browser tests share a
    page within a module)."""
    if not getattr(config.option, "numprocesses", None):
        return
    measured = _measured_s()
    items.sort(key=lambda item: -measured.get(item.nodeid, 0.0))
