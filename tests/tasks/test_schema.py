"""Task-sequence schema: round trips, examples, and bad files that name field and line."""

from pathlib import Path

import pytest

from core.yaml_validation import FileFormatError
from tasks import BasePose, BaseSubtask, EEPose, EESubtask, TaskSequence, load_sequence, parse_sequence
from tasks.sequence_file import EXAMPLES_DIR, save_sequence, sequence_to_yaml


def test_examples_load_and_round_trip(tmp_path):
    paths = sorted(EXAMPLES_DIR.glob("*.yaml"))
    assert {p.stem for p in paths} >= {"navigation_through_boxes", "two_pickups", "aisle_laps"}
    for path in paths:
        seq = load_sequence(path)
        assert seq.subtasks
        out = tmp_path / path.name
        save_sequence(seq, out)
        assert load_sequence(out) == seq
        assert (path.parent / seq.scene).resolve().is_file()


def test_defaults_and_priority_order():
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=1, y=2)),
                                 EESubtask(target=EEPose(position=(1, 2, 1)), dwell_s=2.0)])
    base, ee = seq.subtasks
    assert base.order == ["base", "ee"] and ee.order == ["ee", "base"]
    assert parse_sequence(sequence_to_yaml(seq)) == seq
    custom = BaseSubtask(target=BasePose(x=1, y=2), priority=["ee", "base"])
    assert custom.order == ["ee", "base"]


def test_waypoints_and_goal():
    s = BaseSubtask(waypoints=[BasePose(x=1, y=0), BasePose(x=2, y=1)], target=BasePose(x=3, y=1, yaw_deg=90))
    assert [p.x for p in s.path()] == [1, 2, 3]
    assert s.goal().yaw_rad == pytest.approx(1.5707963)
    only_waypoints = BaseSubtask(waypoints=[BasePose(x=1, y=0)])
    assert only_waypoints.goal().x == 1


def test_ee_rotation_from_rpy():
    import numpy as np

    R = EEPose(position=(0, 0, 1), rpy_deg=(0, 90, 0)).rotation()
    np.testing.assert_allclose(R[:, 0], [0, 0, -1], atol=1e-12)  # tool x axis pointing down
    assert EEPose(position=(0, 0, 1)).rotation() is None


BAD = [
    ("subtasks:\n- kind: base\n  target: {x: .nan, y: 0}\n", "subtasks.0.target.x", 3, "finite"),
    ("subtasks:\n- kind: base\n  target: {x: 1, y: 0}\n  speed: 3\n", "subtasks.0.speed", 4, "Extra"),
    ("subtasks:\n- kind: base\n  target: {x: 1, y: 0}\n  tolerance:\n    position_m: -0.1\n",
     "subtasks.0.tolerance.position_m", 5, "greater than 0"),
    ("subtasks:\n- kind: gripper\n  target: {x: 1, y: 0}\n", "subtasks.0", 2, "tag 'gripper'"),
    ("subtasks:\n- kind: ee\n  target: {position: [1, 2]}\n", "subtasks.0.target.position.2", 3, "required"),
    ("subtasks:\n- kind: ee\n  timeout_s: 0\n  target: {position: [1, 2, 3]}\n", "subtasks.0.timeout_s", 3, ""),
    ("subtasks:\n- kind: base\n", "subtasks.0", 2, "target or waypoints"),
    ("subtasks:\n- kind: base\n  target: {x: 1, y: 0}\n  priority: [base, base]\n", "subtasks.0.priority", 4, ""),
    ("subtasks: [\n  {kind: base\n", "", None, "not valid YAML"),
    ("", "", 1, "empty"),
]


@pytest.mark.parametrize(("text", "field", "line", "msg"), BAD)
def test_bad_files_name_field_and_line(text, field, line, msg):
    with pytest.raises(FileFormatError) as err:
        parse_sequence(text, source="bad.yaml")
    assert any(f == field and (line is None or ln == line) and msg in m for f, ln, m in err.value.problems), \
        err.value.problems
    assert "bad.yaml" in str(err.value)


def test_bad_file_loads_nothing(tmp_path):
    good = tmp_path / "good.yaml"
    save_sequence(TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=1, y=2))]), good)
    text = good.read_text().replace("x: 1.0", "x: .nan")
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    with pytest.raises(FileFormatError):
        load_sequence(bad)
    with pytest.raises(FileFormatError, match="cannot read"):
        load_sequence(Path(tmp_path / "missing.yaml"))
