"""Shared fixtures: one robot model per session (building it parses the URDF)."""

from __future__ import annotations

import pytest

from core.robot import RobotModel


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return RobotModel()
