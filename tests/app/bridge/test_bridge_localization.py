"""Localization through the bridge (a real uvicorn server on 127.0.0.1, the reference sim driver in its own
process, the real runtime live with localization on): a driver whose state is its wheel odometry (the default
`pose_source`) is localized by the runtime against the map it builds from the driver's depth frames, corrections
accepted; a driver that says its pose is already localized (`"pose_source": "localized"`) is used as it is, and no
registration runs on it. `/api/state` and `/api/health` say which."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import httpx
import numpy as np
import pytest

from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from core.localization.gates import Verdict
from core.params import LocalizationParams
from core.types import PoseSource
from tests.app.bridge.conftest import StateStreamer, send_state, wait_until

pytestmark = pytest.mark.wallclock

CORRIDOR_YAML = """name: corridor
walls: false
robot_start: [0.0, 0.0, 0.0]
boxes:
- {id: b0, position: [-1.0, 1.3, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
- {id: b1, position: [0.8, 1.3, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
- {id: b2, position: [2.6, 1.3, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
- {id: b3, position: [-1.0, -1.3, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
- {id: b4, position: [0.8, -1.3, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
- {id: b5, position: [2.6, -1.3, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
- {id: b6, position: [2.2, 0.0, 0.3], size: [0.6, 0.6, 0.6], yaw: 0.0}
"""
"""Boxes on both sides of the robot and one ahead: the base camera sees surfaces that fix x, y and yaw."""


@pytest.fixture
def localizing_runtime(bridge: BridgeServer):
    """A live runtime with localization on (untrusted after 2 s without a correction) that drives the bridge's
    robot, attached to the bridge."""
    localization = replace(LocalizationParams(enabled=True), untrusted_after_s=2.0)
    runtime = Runtime(RuntimeConfig(map_kind="object", localization=localization), backend=bridge.robot)
    bridge.attach(runtime)
    yield runtime
    runtime.shutdown()


def _scene(tmp_path: Path) -> Path:
    path = tmp_path / "corridor.yaml"
    path.write_text(CORRIDOR_YAML)
    return path


def test_the_state_says_what_the_pose_is_and_the_robot_reports_it(bridge: BridgeServer, raw_driver) -> None:
    """`pose_source` is odometry unless the driver says its pose is localized; the bridge's robot reports it with
    every observation, and /api/health shows the latest."""
    send_state(raw_driver, 1.0)
    assert wait_until(lambda: bridge.link.state is not None)
    assert bridge.robot.observe().pose_source == PoseSource.ODOMETRY
    assert httpx.get(f"{bridge.url}/api/health", timeout=30).json()["pose_source"] == "odometry"
    send_state(raw_driver, 1.01, pose_source="localized")
    assert wait_until(lambda: bridge.link.pose_source == PoseSource.LOCALIZED)
    assert bridge.robot.observe().pose_source == PoseSource.LOCALIZED
    health = httpx.get(f"{bridge.url}/api/health", timeout=30).json()
    assert health["pose_source"] == "localized" and health["localized_by"] is None  # no runtime attached


def test_the_localizer_counts_from_the_drivers_first_state_not_from_zero(bridge: BridgeServer, raw_driver) -> None:
    """A runtime made before the driver's first state begins at the placeholder's t = 0; a driver's steady clock
    may read hours: the time without a correction counts from its first state, so the pose is not untrusted at
    once."""
    rt = Runtime(RuntimeConfig(map_kind="object", localization=LocalizationParams(enabled=True)),
                 backend=bridge.robot)
    try:
        loop = rt.closed_loop
        assert loop.state.t == 0.0
        with StateStreamer(raw_driver, t0=5000.0):
            assert wait_until(lambda: bridge.link.state is not None)
            loop.observe(0.01)
        health = loop.health(loop.state.t)
        assert loop.state.t >= 5000.0 and health is not None
        assert health.untrusted is None and health.since_accepted_s < 1.0, health
    finally:
        rt.shutdown()


@pytest.mark.slow
def test_a_driver_that_sends_odometry_is_localized_by_the_runtime(bridge, start_driver, localizing_runtime, api,
                                                                   tmp_path):
    driver = start_driver("--scene", str(_scene(tmp_path)))
    rt = localizing_runtime
    rt.start_live()
    loop = rt.closed_loop
    localizer = loop.localizer
    assert localizer is not None
    assert wait_until(lambda: localizer.counts[Verdict.ACCEPTED.value] >= 2, timeout_s=120), \
        (dict(localizer.counts), rt.status_line(), driver.output[-2000:])
    assert loop.pose_source == PoseSource.ODOMETRY and loop.localizing
    assert rt.live is not None and rt.live.localization is not None
    assert rt.live.localization.threads == {"localization"}
    state = api.get("/api/state").json()  # the latest published snapshot: it may be a registration behind
    assert state["pose_source"] == "odometry"
    assert state["localization"]["by"] == "localizer"
    assert wait_until(lambda: api.get("/api/state").json()["localization"]["accepted"] >= 2, timeout_s=30)
    health = api.get("/api/health").json()
    assert health["pose_source"] == "odometry" and health["localized_by"] == "localizer"
    assert rt.snapshot().localization is not None


@pytest.mark.slow
def test_a_driver_that_sends_a_localized_pose_is_used_as_it_is(bridge, start_driver, localizing_runtime, api,
                                                               tmp_path):
    driver = start_driver("--scene", str(_scene(tmp_path)), "--pose-source", "localized")
    rt = localizing_runtime
    rt.start_live()
    loop = rt.closed_loop
    localizer = loop.localizer
    assert localizer is not None
    assert wait_until(lambda: loop.pose_source == PoseSource.LOCALIZED, timeout_s=30)
    # well past `untrusted_after_s` of the driver's time, with its frames mapped all along
    start_t = rt.time
    assert wait_until(lambda: rt.time > start_t + 5.0 and len(rt.map.snapshot().objects) >= 3, timeout_s=120), \
        (rt.time, rt.status_line(), driver.output[-2000:])
    assert not loop.localizing
    assert sum(localizer.tally.values()) == 0 and not localizer.corrections, "no registration ran"
    assert rt.live is not None and rt.live.localization is not None
    assert rt.live.localization.registrations == 0
    assert not np.any(localizer.world_from_odom), "the pose is the driver's, not re-posed"
    link_state = bridge.robot.link.state
    assert link_state is not None
    np.testing.assert_allclose(loop.state.q[:3], link_state.q[:3], atol=0.05)  # the driver's pose (a state apart)
    assert rt.problems.count(ProblemKind.LOCALIZATION) == 0, "no health of the localizer's while it is off"
    snap = rt.snapshot()
    assert snap.localization is None and snap.pose_source == PoseSource.LOCALIZED
    assert "localization untrusted" not in snap.status
    state = api.get("/api/state").json()
    assert state["pose_source"] == "localized"
    assert state["localization"] == {"by": "driver", "accepted": None, "rejected": None, "degenerate": None,
                                     "no_reference": None, "sigma_xy_m": None, "since_accepted_s": None,
                                     "untrusted": None}
    health = httpx.get(f"{bridge.url}/api/health", timeout=30).json()
    assert health["pose_source"] == "localized" and health["localized_by"] == "driver"


def test_the_wire_literal_names_every_pose_source_and_nothing_else() -> None:
    """The driver-facing `PoseSourceIn` (a plain literal, so a driver needs no enum) is `PoseSource`'s values."""
    from typing import get_args

    from app.bridge.protocol import PoseSourceIn

    assert set(get_args(PoseSourceIn)) == {source.value for source in PoseSource}
