import pytest

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from core.sim.world import SimWorld


@pytest.fixture
def world(robot) -> SimWorld:
    return SimWorld(robot)
