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



def test_selection_follows_the_subtask_through_undo():
    from app.ui.authoring import describe_change, follow_selection

    abc = TaskSequence(subtasks=[add_base_goal(TaskSequence(), x, 0, None, name=n).subtasks[0]
                                 for n, x in (("A", 1), ("B", 2), ("C", 3))])
    bac = move_subtask(abc, 0, 1)
    assert follow_selection(bac, abc, 1) == 0  # A stays selected where the undo put it
    assert describe_change(bac, abc) == "subtask 1 'A' changed"
    ab = delete_subtask(abc, 2)
    assert follow_selection(ab, abc, 1) == 1  # B stays selected after the delete of C is undone
    assert describe_change(ab, abc) == "subtask 3 'C' back"
    assert describe_change(abc, ab) == "subtask 3 'C' removed"
    renamed = replace_subtask(abc, 1, name="B2")
    assert follow_selection(renamed, abc, 1) == 1  # the renamed subtask is the changed one
    assert follow_selection(abc, TaskSequence(), 0) is None
