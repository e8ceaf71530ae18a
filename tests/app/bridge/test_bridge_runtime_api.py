"""The operator API over real HTTP against a real `Runtime`: status, sequence loading, run control and
scene edits on the embedded simulation; refusals when the runtime drives a robot through the bridge."""

from __future__ import annotations

import json

import httpx
import numpy as np
import pytest

from app.bridge.attachment import RuntimeAttachment
from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from core.sim.sim_robot import SimRobot
from tests.app.bridge.conftest import BAD_SEQUENCE as BAD
from tests.app.bridge.conftest import EXAMPLE_SEQUENCE as EXAMPLE
from tests.app.bridge.conftest import StateStreamer, wait_until

pytestmark = pytest.mark.wallclock


def test_status_routes_report_the_runtime(api: httpx.Client, sim_runtime) -> None:
    state = api.get("/api/state").json()
    assert len(state["q"]) == 9 and state["run_state"] == "idle"
    assert api.get("/api/plan").json() == {"run_state": "idle", "plan": None}
    progress = api.get("/api/progress").json()
    assert [s["outcome"] for s in progress["subtasks"]] == ["pending"] * len(sim_runtime.sequence.subtasks)
    assert api.get("/api/sequence").json()["name"] == sim_runtime.sequence.name
    assert api.get("/api/health").json()["run_state"] == "idle"


def test_loading_a_sequence_replaces_it_and_a_bad_one_changes_nothing(api: httpx.Client, sim_runtime) -> None:
    version = sim_runtime.sequence_version
    refused = api.put("/api/sequence", json={"yaml": BAD})
    assert refused.status_code == 422
    assert refused.json()["problems"][0] == {"field": "subtasks.0.target.y", "line": 5,
                                             "message": "Input should be a valid number, unable to parse string "
                                                        "as a number"}
    assert sim_runtime.sequence_version == version
    loaded = api.put("/api/sequence", json={"yaml": EXAMPLE}).json()
    assert loaded["version"] == version + 1 and loaded["subtasks"] == 4
    assert sim_runtime.sequence.name == "two pick-up stops"


INTO_BOX_A = """name: into a box
subtasks:
- name: onto box_a
  kind: base
  target: {x: 2.2, y: 1.3}
"""


def test_targets_are_checked_against_the_scene(api: httpx.Client, sim_runtime) -> None:
    """The default scene's box_a stands at (2.2, 1.3): a base goal there is refused with its line and the nearest
    acceptable goal; told that the scene will change, the bridge loads it with a warning."""
    version = sim_runtime.sequence_version
    refused = api.put("/api/sequence", json={"yaml": INTO_BOX_A})
    assert refused.status_code == 422
    (problem,) = refused.json()["problems"]
    assert problem["field"] == "subtasks.0.target" and problem["line"] == 5
    assert "box_a" in problem["message"] and "nearest acceptable: (" in problem["message"]
    assert sim_runtime.sequence_version == version
    checked = api.post("/api/sequence/validate", json={"yaml": INTO_BOX_A}).json()
    assert not checked["valid"] and checked["problems"][0]["line"] == 5
    loaded = api.put("/api/sequence", json={"yaml": INTO_BOX_A, "scene_may_change": True}).json()
    assert loaded["version"] == version + 1 and "scene may change" in loaded["warnings"][0]


def test_run_control_follows_the_runtime(api: httpx.Client, sim_runtime) -> None:
    assert api.post("/api/run/start").json()["run_state"] == "running"
    assert api.post("/api/run/step").status_code == 409
    assert api.post("/api/run/pause").json()["run_state"] == "paused"
    assert api.post("/api/run/step", json={"seconds": 0.5}).json()["run_state"] == "paused"
    skipped = api.post("/api/run/skip").json()
    assert sim_runtime.sequencer.progress[0].outcome.value == "skipped", skipped
    assert api.post("/api/run/stop").json()["run_state"] == "idle"
    assert api.post("/api/run/skip").status_code == 409  # nothing active
    assert api.post("/api/run/emergency-stop").json()["run_state"] == "emergency_stop"
    assert api.post("/api/run/reset").json()["run_state"] == "idle"
    assert api.post("/api/run/config", json={"constraint": "edf", "speed": 2.0}).status_code == 200
    assert sim_runtime.config.constraint == "edf" and sim_runtime.config.speed == 2.0


def test_scene_edits_while_simulating(api: httpx.Client, sim_runtime) -> None:
    added = api.post("/api/scene/boxes", json={"id": "crate", "position": [3.0, 2.0, 0.3]})
    assert added.status_code == 201 and added.json()["size"] == [0.6, 0.6, 0.6]
    assert "crate" in {b["id"] for b in api.get("/api/scene").json()["boxes"]}
    moved = api.put("/api/scene/boxes/crate", json={"position": [3.5, 2.0, 0.3], "yaw": 0.5}).json()
    assert moved["position"] == [3.5, 2.0, 0.3] and moved["yaw"] == 0.5
    assert api.put("/api/scene/boxes/ghost", json={"position": [0, 0, 0]}).status_code == 404
    inside = api.post("/api/scene/boxes", json={"id": "inside", "position": [0.0, 0.0, 0.3]})
    assert inside.status_code == 422 and inside.json()["detail"]
    assert api.delete("/api/scene/boxes/crate").json()["id"] == "crate"
    assert "crate" not in {b.id for b in sim_runtime.scene().boxes}
    assert len(api.post("/api/scene/randomise", json={"seed": 3, "n_boxes": 8}).json()["boxes"]) >= 8


def test_a_runtime_on_the_bridge_refuses_simulation_only_requests(api: httpx.Client, bridge: BridgeServer,
                                                                  bridge_runtime) -> None:
    assert api.get("/api/scene").status_code == 409
    assert api.post("/api/scene/boxes", json={"id": "crate", "position": [3.0, 2.0, 0.3]}).status_code == 409
    speed = api.post("/api/run/config", json={"speed": 2.0})
    assert speed.status_code == 409 and "a backend the runtime steps" in speed.json()["detail"]
    ground_truth = api.post("/api/run/config", json={"map_kind": "ground_truth"})
    assert ground_truth.status_code == 409 and "ground-truth map" in ground_truth.json()["detail"]
    assert api.post("/api/run/pause").json()["run_state"] == "paused"
    step = api.post("/api/run/step")
    assert step.status_code == 409 and "a backend the runtime steps" in step.json()["detail"]


def test_the_attachment_asks_the_backends_abilities(bridge: BridgeServer, sim_runtime) -> None:
    """Step and speed follow `steps_in_lockstep`, scene edits and the ground-truth map `simulated`
    (docs/design.md, "Writing a new backend"), never the backend's class."""
    assert isinstance(sim_runtime.backend, SimRobot)
    abilities = sim_runtime.backend.abilities
    attached = RuntimeAttachment(sim_runtime)
    assert (attached.steps, attached.simulates) == (abilities.steps_in_lockstep, abilities.simulated) == (True, True)
    remote = RuntimeAttachment(Runtime(RuntimeConfig(map_process=False), backend=bridge.robot))
    try:
        assert (remote.steps, remote.simulates) == (False, False)
    finally:
        remote.runtime.shutdown()


def test_start_needs_fresh_robot_state(api: httpx.Client, bridge: BridgeServer, bridge_runtime) -> None:
    refused = api.post("/api/run/start")
    assert refused.status_code == 409 and "no fresh robot state" in refused.json()["detail"]
    assert bridge_runtime.run_state.value == "idle"


@pytest.mark.slow
def test_start_with_a_driver_connected(api: httpx.Client, bridge: BridgeServer, bridge_runtime, start_driver) -> None:
    start_driver()
    assert api.post("/api/run/start").json()["run_state"] == "running"


def _next_command(ws) -> dict:
    while True:
        msg = json.loads(ws.recv(timeout=5))
        if msg["type"] == "command":
            return msg


def test_zero_commands_say_why_the_robot_may_not_move(bridge: BridgeServer, bridge_runtime, raw_driver) -> None:
    """Idle, paused, stopped runs send `not_running`, an emergency stop `emergency_stop`; `runtime` only while
    the run runs (the controller's command, zero or not): a driver never has to guess."""
    robot = bridge.robot
    steps = [(lambda: None, 0.0), (bridge_runtime.start, 0.0), (lambda: None, 0.1), (bridge_runtime.pause, 0.1),
             (bridge_runtime.emergency_stop, 0.0)]
    sent, on_the_wire = [], []
    with StateStreamer(raw_driver):
        assert wait_until(lambda: not bridge.link.is_stale())
        for change, speed in steps:  # one at a time: commands are latest-wins, a newer one drops an unsent one
            change()
            sent.append(robot.send(np.full(9, speed), 1.0).reason)
            on_the_wire.append(_next_command(raw_driver))
    assert sent == ["not_running", "runtime", "runtime", "not_running", "emergency_stop"]
    assert [c["reason"] for c in on_the_wire] == sent
    assert [c["qdot"] != [0.0] * 9 for c in on_the_wire] == [False, False, True, False, False]


def test_progress_after_start_never_shows_a_snapshot_begun_before_it(api: httpx.Client, sim_runtime) -> None:
    """The publish thread may assemble a snapshot before Start and hand it over after: the operator API must
    not answer /api/progress with that idle view once Start has answered running."""
    before = sim_runtime.snapshot()  # begun (and assembled) while idle, delivered late below
    assert before.run_state.value == "idle"
    assert api.post("/api/run/start").json()["run_state"] == "running"
    for callback in list(sim_runtime._subscribers):
        callback(before)
    assert api.get("/api/progress").json()["run_state"] == "running"
    assert api.post("/api/run/stop").json()["run_state"] == "idle"
