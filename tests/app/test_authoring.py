import pytest
from pydantic import ValidationError

from app.ui.authoring import (
    SequenceHistory,
    add_base_goal,
    add_base_waypoint,
    add_ee_target,
    delete_subtask,
    move_subtask,
    replace_subtask,
)
from tasks import TaskSequence, parse_sequence, sequence_to_yaml


def test_edits_build_a_valid_sequence():
    seq = add_base_goal(TaskSequence(), 1.0, 2.0, 90.0)
    seq = add_base_waypoint(seq, 0, 0.5, 1.0)
    seq = add_ee_target(seq, (2.0, 2.0, 0.8), (0.0, 90.0, 0.0), dwell_s=2.0)
    assert [s.kind for s in seq.subtasks] == ["base", "ee"]
    assert seq.subtasks[0].waypoints[0].x == 0.5 and seq.subtasks[1].dwell_s == 2.0
    assert parse_sequence(sequence_to_yaml(seq)) == seq
    seq = move_subtask(seq, 1, -1)
    assert [s.kind for s in seq.subtasks] == ["ee", "base"]
    assert move_subtask(seq, 0, -1) == seq
    seq = replace_subtask(seq, 0, tolerance={"position_m": 0.02}, timeout_s=10.0, priority=["base", "ee"])
    assert seq.subtasks[0].tolerance.position_m == 0.02 and seq.subtasks[0].order == ["base", "ee"]
    assert len(delete_subtask(seq, 0).subtasks) == 1


def test_invalid_edits_are_refused_and_change_nothing():
    seq = add_base_goal(TaskSequence(), 1.0, 2.0, None)
    with pytest.raises(ValidationError):
        replace_subtask(seq, 0, tolerance={"position_m": -1.0})
    with pytest.raises(ValidationError):
        replace_subtask(seq, 0, timeout_s=float("nan"))
    with pytest.raises(ValueError, match="EE subtask"):
        add_base_waypoint(add_ee_target(seq, (1, 1, 1), None), 1, 0.0, 0.0)
    assert seq.subtasks[0].tolerance.position_m == 0.1


def test_undo_redo():
    h = SequenceHistory(TaskSequence())
    a = h.push(add_base_goal(h.current, 1, 0, None))
    b = h.push(add_base_goal(h.current, 2, 0, None))
    assert h.undo() == a and h.undo() == TaskSequence() and not h.can_undo
    assert h.redo() == a and h.can_redo
    h.push(add_base_goal(a, 5, 5, None))
    assert not h.can_redo and h.current != b

