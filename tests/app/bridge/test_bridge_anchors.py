"""Anchored targets over the bridge: `/validate` and `PUT /api/sequence` take them, refuse a bad anchor with
its field and line, and check an anchored target where its (simulated) box is."""

from __future__ import annotations

import httpx

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
