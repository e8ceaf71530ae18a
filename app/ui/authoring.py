"""Authoring a task sequence: pure edits on immutable `TaskSequence` values, with undo/redo.

The studio's authoring panel calls these; every edit is validated by the schema, so an invalid
value is refused with the schema's message and the sequence stays as it was.
"""

from __future__ import annotations

from typing import Any

from tasks.schema import BasePose, BaseSubtask, EEPose, EESubtask, TaskSequence

PRIORITY_CHOICES = {"default": None, "base > ee": ["base", "ee"], "ee > base": ["ee", "base"],
                    "base only": ["base"], "ee only": ["ee"]}


def add_base_goal(seq: TaskSequence, x: float, y: float, yaw_deg: float | None, name: str = "") -> TaskSequence:
    """Append a base subtask to (x, y[, yaw])."""
    sub = BaseSubtask(name=name or f"base to ({x:.2f}, {y:.2f})", target=BasePose(x=x, y=y, yaw_deg=yaw_deg))
    return seq.model_copy(update={"subtasks": [*seq.subtasks, sub]})


def add_base_waypoint(seq: TaskSequence, index: int, x: float, y: float) -> TaskSequence:
    """Insert a waypoint before the target of base subtask `index`."""
    sub = seq.subtasks[index]
    if not isinstance(sub, BaseSubtask):
        raise ValueError(f"subtask {index + 1} is an EE subtask: base waypoints go into base subtasks")
    return replace_subtask(seq, index, waypoints=[*sub.waypoints, BasePose(x=x, y=y)])


def add_ee_target(seq: TaskSequence, position: tuple[float, float, float], rpy_deg: tuple[float, float, float] | None,
                  dwell_s: float = 0.0, name: str = "") -> TaskSequence:
    """Append an EE subtask to a pose."""
    sub = EESubtask(name=name or f"EE to ({position[0]:.2f}, {position[1]:.2f}, {position[2]:.2f})",
                    target=EEPose(position=position, rpy_deg=rpy_deg), dwell_s=dwell_s)
    return seq.model_copy(update={"subtasks": [*seq.subtasks, sub]})


def move_subtask(seq: TaskSequence, index: int, delta: int) -> TaskSequence:
    """Move subtask `index` up (delta −1) or down (+1); out-of-range moves change nothing."""
    j = index + delta
    if not (0 <= index < len(seq.subtasks)) or not (0 <= j < len(seq.subtasks)):
        return seq
    subs = list(seq.subtasks)
    subs[index], subs[j] = subs[j], subs[index]
    return seq.model_copy(update={"subtasks": subs})


def delete_subtask(seq: TaskSequence, index: int) -> TaskSequence:
    if not 0 <= index < len(seq.subtasks):
        raise IndexError(f"no subtask {index + 1}")
    return seq.model_copy(update={"subtasks": [s for i, s in enumerate(seq.subtasks) if i != index]})


def replace_subtask(seq: TaskSequence, index: int, **fields: Any) -> TaskSequence:
    """Subtask `index` with some fields changed, validated by the schema (raises on bad values)."""
    sub = seq.subtasks[index]
    data = sub.model_dump()
    for key, value in fields.items():
        if key == "tolerance":
            data["tolerance"] = {**data["tolerance"], **value}
        else:
            data[key] = value
    new = type(sub).model_validate(data)
    subs = list(seq.subtasks)
    subs[index] = new
    return TaskSequence.model_validate({**seq.model_dump(), "subtasks": [s.model_dump() for s in subs]})


class SequenceHistory:
    """The authored sequence with undo and redo (bounded)."""

    def __init__(self, initial: TaskSequence, limit: int = 200) -> None:
        self._past: list[TaskSequence] = [initial]
        self._future: list[TaskSequence] = []
        self.limit = limit

    @property
    def current(self) -> TaskSequence:
        return self._past[-1]

    def push(self, seq: TaskSequence) -> TaskSequence:
        """Make `seq` current; the redo list is cleared."""
        if seq != self.current:
            self._past.append(seq)
            self._past = self._past[-self.limit:]
            self._future.clear()
        return seq

    @property
    def can_undo(self) -> bool:
        return len(self._past) > 1

    @property
    def can_redo(self) -> bool:
        return bool(self._future)

    def undo(self) -> TaskSequence:
        if self.can_undo:
            self._future.append(self._past.pop())
        return self.current

    def redo(self) -> TaskSequence:
        if self.can_redo:
            self._past.append(self._future.pop())
        return self.current


def follow_selection(before: TaskSequence, after: TaskSequence, selected: int | None) -> int | None:
    """Where the selection goes when `before` becomes `after` by undo or redo: the same subtask if it is still
    there, else the first subtask that changed (so the next Delete never hits a subtask the operator did not
    pick), else none."""
    if selected is not None and 0 <= selected < len(before.subtasks):
        sub = before.subtasks[selected]
        same = [i for i, s in enumerate(after.subtasks) if s == sub]
        if same:
            return min(same, key=lambda i: abs(i - selected))
    changed = next((i for i, (a, b) in enumerate(zip(before.subtasks, after.subtasks, strict=False)) if a != b),
                   min(len(before.subtasks), len(after.subtasks)))
    return changed if changed < len(after.subtasks) else (len(after.subtasks) - 1 if after.subtasks else None)


def describe_change(before: TaskSequence, after: TaskSequence) -> str:
    """One line for the operator saying what an undo or redo changed."""
    if before.name != after.name:
        return f"sequence name '{before.name}' → '{after.name}'"
    n0, n1 = len(before.subtasks), len(after.subtasks)
    if n1 > n0:
        i = follow_selection(before, after, None)
        return f"subtask {i + 1} '{after.subtasks[i].name}' back" if i is not None else "a subtask back"
    if n1 < n0:
        i = next((k for k, (a, b) in enumerate(zip(before.subtasks, after.subtasks, strict=False)) if a != b), n1)
        return f"subtask {i + 1} '{before.subtasks[i].name}' removed"
    i = follow_selection(before, after, None)
    return f"subtask {i + 1} '{after.subtasks[i].name}' changed" if i is not None else "no change"
