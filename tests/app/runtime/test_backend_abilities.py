"""What a robot backend can do is declared by the backend (`RobotBackend.abilities`), and the runtime asks it
instead of checking the backend's class (docs/design.md, "Writing a new backend")."""

import ast
from dataclasses import FrozenInstanceError, replace
from pathlib import Path

import pytest

from app.bridge.bridge_robot import BridgeRobot
from app.bridge.robot_link import RobotLink
from app.runtime import Runtime, RuntimeConfig
from core.params import MappingParams, SensorParams
from core.scene import Scene
from core.sim.sim_robot import SimRobot
from core.sim.simulated_backend import is_simulated
from core.sim.world import SimWorld
from core.types import BackendAbilities, steps_in_lockstep

RUNTIME_DIR = Path(__file__).parents[3] / "app" / "runtime"
BACKEND_CLASSES = {"SimRobot", "BridgeRobot"}


@pytest.fixture
def sim_robot(robot):
    sim = SimRobot(SimWorld(robot, scene=Scene()), cameras=())
    yield sim
    sim.close()


def test_the_simulation_declares_lockstep_a_world_and_its_camera_latency(sim_robot):
    abilities = sim_robot.abilities
    assert abilities.steps_in_lockstep and abilities.simulated
    assert abilities.camera_latency_s == sim_robot.sensor.camera_time_offset_s
    assert steps_in_lockstep(sim_robot) and is_simulated(sim_robot)
    sim_robot.set_sensor(replace(SensorParams.ideal(), camera_time_offset_s=0.07))
    assert sim_robot.abilities.camera_latency_s == 0.07  # it follows the sensor model it perceives through


def test_the_bridge_declares_a_real_robot():
    bridge = BridgeRobot(RobotLink())
    assert bridge.abilities == BackendAbilities(steps_in_lockstep=False, simulated=False, camera_latency_s=0.0)
    assert not steps_in_lockstep(bridge) and not is_simulated(bridge)
    with pytest.raises(FrozenInstanceError):
        bridge.abilities.steps_in_lockstep = True  # type: ignore[misc]


def test_lockstep_refuses_a_backend_that_cannot_step():
    rt = Runtime(RuntimeConfig(map_process=False), backend=BridgeRobot(RobotLink()))
    try:
        assert rt.world is None
        with pytest.raises(RuntimeError, match=r"lockstep needs the embedded simulation: .*BridgeRobot.* cannot be "
                                               r"stepped"):
            rt.run_lockstep(1.0)
        with pytest.raises(RuntimeError, match="real robot runs in real time"):
            rt.set_speed(2.0)
        assert rt.time == 0.0
    finally:
        rt.shutdown()


def test_the_camera_latency_is_the_calibrated_one_else_the_declared_one():
    bridge = Runtime(RuntimeConfig(map_process=False), backend=BridgeRobot(RobotLink()))
    calibrated = Runtime(RuntimeConfig(map_process=False, mapping=MappingParams(camera_latency_s=0.03)),
                         backend=BridgeRobot(RobotLink()))
    sim = Runtime(RuntimeConfig(map_kind="object", map_process=False), scene=Scene())
    try:
        assert bridge.closed_loop.camera_latency_s() == 0.0
        assert calibrated.closed_loop.camera_latency_s() == 0.03
        assert isinstance(sim.backend, SimRobot)
        declared = sim.backend.sensor.camera_time_offset_s
        assert declared > 0 and sim.closed_loop.camera_latency_s() == declared
    finally:
        for rt in (bridge, calibrated, sim):
            rt.shutdown()


def _isinstance_on_a_backend_class(path: Path) -> list[str]:
    """`isinstance(x, SimRobot)`-like calls in a file (a tuple of classes counts too)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance":
            names = {n.id for arg in node.args[1:] for n in ast.walk(arg) if isinstance(n, ast.Name)}
            names |= {n.attr for arg in node.args[1:] for n in ast.walk(arg) if isinstance(n, ast.Attribute)}
            if names & BACKEND_CLASSES:
                found.append(f"{path.name}:{node.lineno}")
    return found


def test_the_runtime_never_asks_which_backend_it_drives(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("isinstance(b, SimRobot)\nisinstance(b, (int, bridge_robot.BridgeRobot))\nisinstance(m, Map)\n")
    assert _isinstance_on_a_backend_class(probe) == ["probe.py:1", "probe.py:2"]  # the check sees them
    files = sorted(RUNTIME_DIR.glob("*.py"))
    assert len(files) > 5
    everywhere = sorted(RUNTIME_DIR.parent.rglob("*.py"))  # the UI, the bridge, recordings and the CLI ask too
    assert len(everywhere) > 3 * len(files)
    found = [hit for path in everywhere for hit in _isinstance_on_a_backend_class(path)]
    assert found == [], f"ask the backend's abilities instead: {found}"
    imports_bridge = [p.name for p in files if "app.bridge" in p.read_text(encoding="utf-8")]
    assert imports_bridge == [], "the runtime knows no bridge"
