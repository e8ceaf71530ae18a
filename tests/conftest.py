"""Shared fixtures: one robot model per session (building it parses the URDF)."""

from __future__ import annotations

import pytest

from core.robot import RobotModel


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--schemathesis-full", action="store_true",
                     help="fuzz the bridge's operator API with at least 2,000 cases (default: at least 500)")


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return RobotModel()
