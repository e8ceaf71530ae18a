"""Anchored targets over the bridge: `/validate` and `PUT /api/sequence` take them, refuse a bad anchor with
its field and line, and check an anchored target where its (simulated) box is."""

from __future__ import annotations

import httpx
import pytest

pytestmark = pytest.mark.wallclock

ANCHORED = """name: anchored
objects:
  box_a: {}
subtasks:
- name: approach box_a
  kind: base
  target: {anchor: {object: box_a, face: front, offset: [-0.9, 0, 0]}}
"""


def test_validate_refuses_a_bad_anchor_with_field_and_line(api: httpx.Client) -> None:
    bad = ANCHORED.replace("object: box_a, face: front", "object: box_z, face: front")
    out = api.post("/api/sequence/validate", json={"yaml": bad}).json()
    assert out["valid"] is False
    assert [(p["field"], p["line"]) for p in out["problems"]] == [("subtasks.0.target.anchor.object", 7)]
    assert "unknown object 'box_z'" in out["problems"][0]["message"]
    out = api.post("/api/sequence/validate", json={"yaml": ANCHORED.replace("face: front", "face: bottom")}).json()
    assert [(p["field"], p["line"]) for p in out["problems"]] == [("subtasks.0.target.anchor.face", 7)]


def test_put_takes_an_anchored_sequence_checked_where_its_box_is(api: httpx.Client, sim_runtime) -> None:
    response = api.put("/api/sequence", json={"yaml": ANCHORED})
    assert response.status_code == 200, response.text
    assert sim_runtime.sequence.subtasks[0].target.anchor.object == "box_a"
    assert "anchor:" in response.json()["yaml"]
    # box_a's front at x = 1.9: 0.1 m off it the base is inside its clearance, refused with the line
    near = ANCHORED.replace("[-0.9, 0, 0]", "[-0.1, 0, 0]")
    response = api.put("/api/sequence", json={"yaml": near})
    assert response.status_code == 422
    problems = response.json()["problems"]
    assert [(p["field"], p["line"]) for p in problems] == [("subtasks.0.target", 7)]
    assert "box_a" in problems[0]["message"]


def test_progress_tells_where_an_anchored_goal_is_placed(api: httpx.Client, sim_runtime) -> None:
    """A program driving the robot through the bridge sees what a subtask is anchored on and where its goal is now
    (box_a's front face 0.9 m before it), as the studio does."""
    assert api.put("/api/sequence", json={"yaml": ANCHORED}).status_code == 200
    sim_runtime.run_lockstep(1.0, until_done=False, publish_every=1)
    subtask = api.get("/api/progress").json()["subtasks"][0]
    assert subtask["anchor_object"] == "box_a" and subtask["anchor"] == "front of box_a + (-0.9, 0, 0)"
    box = sim_runtime.require_world().box("box_a")
    front = box.position[0] - box.size[0] / 2
    assert subtask["anchored_goal"] is not None
    x, y, _ = subtask["anchored_goal"]
    assert abs(x - (front - 0.9)) < 0.05 and abs(y - box.position[1]) < 0.05  # where the map has box_a
