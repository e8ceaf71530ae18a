"""The closed loop hands the map each frame at its exposure: with the simulated camera's latency (stamped
late at the pose of the stamp) a pole seen while the base turns is mapped where it stands, not turned
by yaw rate × latency; with the compensation off (`camera_latency_s` = 0) it is."""

from dataclasses import replace

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from core.params import MappingParams, SensorParams, SimParams
from core.robot.model import READY_Q
from core.scene import Box, Scene

LATENCY_S = 0.05
YAW_RATE = 0.75
POLE = Box("pole", (2.0, 0.0, 0.6), (0.12, 0.12, 1.2))


def _mapped_pole_bearing(camera_latency_s: float | None) -> float:
    sensor = replace(SensorParams.ideal(), camera_time_offset_s=LATENCY_S)
    config = RuntimeConfig(scene=None, map_kind="object", map_process=False, sim=SimParams(sensor=sensor),
                           mapping=MappingParams(camera_latency_s=camera_latency_s))
    rt = Runtime(config, scene=Scene((POLE,)))
    q = READY_Q.copy()
    q[2] = -0.35
    rt.world.set_robot(q)
    loop, backend = rt.closed_loop, rt.backend
    turn = np.zeros(9)
    turn[2] = YAW_RATE
    for _ in range(90):  # 0.9 s: the pole crosses the base camera's view
        state = loop.observe(0.01)
        loop.integrate_frames(state.t)
        backend.command(turn, state.t)
        backend.step(0.01)
    objects = list(loop.map.objects.values())
    assert len(objects) == 1, f"one pole, {len(objects)} objects"
    centre = objects[0].solid_pose[:3, 3]
    return float(np.arctan2(centre[1], centre[0]))


@pytest.mark.parametrize(("latency", "expected"), [(None, 0.0), (0.0, YAW_RATE * LATENCY_S)])
def test_frames_reach_the_map_at_their_exposure(latency, expected):
    assert _mapped_pole_bearing(latency) == pytest.approx(expected, abs=0.008)
