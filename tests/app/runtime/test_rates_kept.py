"""A configured rate the live loops cannot keep is a problem the operator sees, not a silently slower loop: cameras
faster than the map can integrate (both at one frame per physics step) count their skipped frames in the
problems log, by camera, with how many in all."""

from __future__ import annotations

from dataclasses import replace

import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from core.params import CameraParams, SimParams
from tests.app.bridge.conftest import wait_until

pytestmark = pytest.mark.wallclock

FAST = CameraParams(rate_hz=100.0)
"""One frame per 10 ms physics step from each camera: two frames every 10 ms, more than the map integrates."""


@pytest.mark.slow
def test_cameras_faster_than_the_map_are_a_problem_with_the_frames_it_skipped() -> None:
    sim = replace(SimParams(), base_camera=FAST, hand_camera=FAST)
    rt = Runtime(RuntimeConfig(map_kind="object", sim=sim))
    try:
        rt.start_live()
        assert wait_until(lambda: rt.closed_loop.problems.count(ProblemKind.FRAMES_SKIPPED) > 0, timeout_s=60.0), \
            "two cameras at 100 Hz and no frame skipped"
        problem = {c.kind: c for c in rt.closed_loop.problems.counts()}[ProblemKind.FRAMES_SKIPPED]
        assert "the map fell behind the" in problem.last_message and "skipped" in problem.last_message
        assert rt.closed_loop.frames_skipped >= problem.count
    finally:
        rt.shutdown()
