"""`RuntimeConfig` refuses what no run can use, wherever it is built or changed."""

import math
from dataclasses import replace

import pytest

from app import cli
from app.runtime import RuntimeConfig
from app.runtime.config import SPEED_RANGE


@pytest.mark.parametrize("speed", [99.0, 20.5, 0.0, 0.01, -1.0, math.nan, math.inf])
def test_a_speed_outside_the_range_is_refused(speed):
    with pytest.raises(ValueError, match="speed must be within"):
        RuntimeConfig(speed=speed)


def test_a_speed_inside_the_range_is_kept_and_checked_again_on_every_change():
    config = RuntimeConfig(speed=SPEED_RANGE[1])
    assert config.speed == SPEED_RANGE[1] and RuntimeConfig(speed=SPEED_RANGE[0]).speed == SPEED_RANGE[0]
    assert config.configured(map_kind="voxel", constraint="edf").speed == SPEED_RANGE[1]
    with pytest.raises(ValueError, match="speed must be within"):
        replace(config, speed=99.0)  # what Runtime.set_speed does


def test_the_cli_refuses_a_speed_outside_the_range_with_exit_status_2(capsys):
    assert cli.main(["--speed", "99"]) == 2
    assert "speed must be within 0.05–20, got 99.0" in capsys.readouterr().err
