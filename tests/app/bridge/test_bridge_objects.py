"""The map's objects over the bridge (real uvicorn on 127.0.0.1): `/api/objects` lists them with name, pose,
extent, E[v] and status; `PUT/DELETE /api/objects/{id}/name` names one (with its declared size) or takes its name
away, and refuses an unknown object, a name taken, a name anchored subtasks use and a NaN size with clear errors."""

from __future__ import annotations

import json

import httpx
import numpy as np
import pytest

from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from core.scene import Box, Scene
from tasks.schema import TaskSequence

pytestmark = pytest.mark.wallclock

SCENE = Scene((Box("crate", (2.5, 0.0, 0.3)), Box("bin", (0.0, 3.0, 0.3), yaw=0.3)), robot_start=(0.0, 0.0, 0.0))
ANCHORED = """name: anchored
objects:
  box_3: {}
subtasks:
- name: reach box_3
  kind: ee
  target: {anchor: {object: box_3, face: top, offset: [-0.25, 0, 0.7], rpy_deg: [0, 90, 0]}}
"""


@pytest.fixture
def truth_runtime(bridge: BridgeServer):
    """A runtime on the ground-truth map (the scene boxes are its objects, ids = box ids), attached."""
    runtime = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=SCENE, sequence=TaskSequence())
    bridge.attach(runtime)
    yield runtime
    runtime.shutdown()


def test_objects_are_listed_named_with_a_size_and_unnamed(api: httpx.Client, truth_runtime: Runtime) -> None:
    listed = api.get("/api/objects").json()
    assert listed["map_kind"] == "ground_truth" and listed["unresolved"] == {}
    crate = next(o for o in listed["objects"] if o["id"] == "crate")
    assert crate["name"] is None and crate["position"] == [2.5, 0.0, 0.3] and crate["extent"] == [0.6, 0.6, 0.6]
    assert crate["status"] == "active" and crate["consistency"] == 1.0 and crate["size"] is None
    named = api.put("/api/objects/crate/name", json={"name": "box_3", "size": [0.6, 0.5, 0.6]})
    assert named.status_code == 200, named.text
    assert named.json()["name"] == "box_3" and named.json()["size"] == [0.6, 0.5, 0.6]
    assert truth_runtime.sequence.objects["box_3"].size == (0.6, 0.5, 0.6)
    assert "box_3" in api.get("/api/sequence").json()["yaml"]
    assert api.put("/api/objects/crate/name", json={"name": "box_3"}).json()["size"] is None  # size taken back
    gone = api.delete("/api/objects/crate/name")
    assert gone.status_code == 200 and gone.json()["name"] is None
    assert "box_3" not in truth_runtime.sequence.objects and truth_runtime.closed_loop.names.bound() == {}


def test_naming_refuses_with_clear_errors(api: httpx.Client, truth_runtime: Runtime) -> None:
    missing = api.put("/api/objects/object_99/name", json={"name": "box_3"})
    assert missing.status_code == 404 and missing.json()["detail"] == "no object #99 in the map"
    assert api.put("/api/objects/crate/name", json={"name": "box_3"}).status_code == 200
    taken = api.put("/api/objects/bin/name", json={"name": "box_3"})
    assert taken.status_code == 409 and taken.json()["detail"] == "box_3 names crate: unname it first"
    other = api.put("/api/objects/crate/name", json={"name": "box_4"})
    assert other.status_code == 409 and other.json()["detail"] == "crate is named box_3: unname it first"
    nan = api.put("/api/objects/bin/name", content=json.dumps({"name": "box_5", "size": [0.6, float("nan"), 0.6]}),
                  headers={"Content-Type": "application/json"})
    assert nan.status_code == 422 and [p["field"] for p in nan.json()["problems"]] == ["body.size.1"]
    for bad in ({"name": "3box"}, {"name": "box_5", "size": [0.6, -0.6, 0.6]}, {"name": "box_5", "size": [0.6]}):
        assert api.put("/api/objects/bin/name", json=bad).status_code == 422, bad
    assert api.delete("/api/objects/bin/name").json()["detail"] == "object 'bin' has no name"
    assert api.put("/api/sequence", json={"yaml": ANCHORED}).status_code == 200
    used = api.delete("/api/objects/crate/name")
    assert used.status_code == 409 and used.json()["detail"].startswith("box_3 is the anchor of subtask 1")
    assert api.put("/api/objects/bin/name", json={"name": "box_5"}, headers={"Authorization": "Bearer no"}
                   ).status_code == 401
    assert truth_runtime.closed_loop.names.bound() == {"box_3": "crate"}


def test_the_object_map_lists_what_it_mapped(api: httpx.Client, sim_runtime: Runtime) -> None:
    """On the object map (the default scene, whole sensor model), after a second of mapping: the objects with
    their E[v], named by their map id."""
    sim_runtime.run_lockstep(1.0, until_done=False, publish_every=1)
    listed = api.get("/api/objects").json()
    assert listed["map_kind"] == "object" and listed["objects"]
    box_a = np.asarray(sim_runtime.require_world().box("box_a").position)
    near = min(listed["objects"], key=lambda o: np.linalg.norm(np.asarray(o["position"][:2]) - box_a[:2]))
    assert np.linalg.norm(np.asarray(near["position"][:2]) - box_a[:2]) < 0.3
    assert near["id"].startswith("object_") and near["label"] == "#" + near["id"].removeprefix("object_")
    assert 0.0 < near["consistency"] <= 1.0 and near["status"] == "active"
    named = api.put(f"/api/objects/{near['id']}/name", json={"name": "box_a2", "size": [0.6, 0.6, 0.6]}).json()
    assert named["name"] == "box_a2" and named["size"] == [0.6, 0.6, 0.6]


def test_a_name_whose_anchored_target_is_out_of_reach_is_refused_and_not_bound(api: httpx.Client,
                                                                                truth_runtime: Runtime) -> None:
    """The sequence anchors a reach 3 m over box_3's top; naming the crate box_3 puts that target out of reach:
    422 with the target check's reason, and the crate stays unnamed (in the map and in the sequence)."""
    high = ANCHORED.replace("offset: [-0.25, 0, 0.7]", "offset: [0, 0, 3.0]")
    assert api.put("/api/sequence", json={"yaml": high}).status_code == 200  # box_3 not bound yet: it would wait
    refused = api.put("/api/objects/crate/name", json={"name": "box_3"})
    assert refused.status_code == 422, refused.text
    assert "the arm reaches" in refused.text
    assert truth_runtime.closed_loop.names.bound() == {}
    crate = next(o for o in api.get("/api/objects").json()["objects"] if o["id"] == "crate")
    assert crate["name"] is None
