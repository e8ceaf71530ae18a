import pytest

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from core.params import MappingParams


@pytest.fixture
def params() -> MappingParams:
    return MappingParams()
