"""`Runtime.name_object` binds the name and saves it with the sequence as one step: when the sequence that
carries the name is refused (its anchored targets checked against the object now named fail), the name is not
left bound either, whatever the exception."""

from __future__ import annotations

import pytest

from app.runtime import Runtime, RuntimeConfig
from core.scene import Box, Scene
from tasks.schema import TaskSequence
from tasks.validation import TargetError

SCENE = Scene((Box("crate", (2.5, 0.0, 0.3)), Box("bin", (0.0, 3.0, 0.3), yaw=0.3)), robot_start=(0.0, 0.0, 0.0))
OUT_OF_REACH = {"name": "anchored", "objects": {"box_3": {}}, "subtasks": [
    {"name": "reach high above box_3", "kind": "ee",
     "target": {"anchor": {"object": "box_3", "face": "top", "offset": [0.0, 0.0, 3.0], "rpy_deg": [0, 90, 0]}}}]}


@pytest.fixture
def runtime():
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=SCENE, sequence=TaskSequence())
    yield rt
    rt.shutdown()


def test_a_name_whose_sequence_is_refused_is_not_left_bound(runtime: Runtime) -> None:
    runtime.set_sequence(TaskSequence.model_validate(OUT_OF_REACH))  # box_3 not named yet: the subtask would wait
    before = runtime.sequence
    with pytest.raises(TargetError):
        runtime.name_object("box_3", "crate")  # 3 m over the crate's top: out of reach once bound
    assert runtime.closed_loop.names.bound() == {}
    assert runtime.sequence is before
    runtime.set_sequence(TaskSequence())
    runtime.name_object("box_3", "crate")  # nothing was left half-done: the name is free to give
    assert runtime.closed_loop.names.bound() == {"box_3": "crate"} and "box_3" in runtime.sequence.objects


def test_a_name_is_taken_back_whatever_refuses_its_sequence(runtime: Runtime, monkeypatch) -> None:
    """Saving the sequence can fail for reasons of its own (here a KeyboardInterrupt while it is replaced)."""
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(runtime.closed_loop, "set_sequence", interrupted)
    with pytest.raises(KeyboardInterrupt):
        runtime.name_object("box_3", "crate")
    assert runtime.closed_loop.names.bound() == {}
