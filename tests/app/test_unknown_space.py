"""Never drive into what the cameras cannot see (issue 27; docs/method.md, "Unknown space is not free"): a box
whose surface returns no depth from the start stands between the robot and its base goal, closed loop, lockstep,
the object map perceiving through the sensor model."""

from dataclasses import replace

import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind, summary_line
from app.runtime.snapshot import RunState
from core.params import MappingParams
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence

DARK = Box("dark", (3.0, 0.0, 0.4), (0.6, 1.2, 0.8), dark=True)
"""Black, glossy or glass: never a depth return, so never mapped."""


@pytest.mark.slow
def test_a_goal_behind_a_box_that_returns_no_depth_is_reached_round_it_without_touching_it():
    scene = Scene((DARK,), robot_start=(0.0, 0.0, 0.0))
    sequence = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=5.0, y=0.0), timeout_s=40.0)])
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=scene, sequence=sequence)  # unknown space: the default
    lines: list[str] = []
    log = rt.run_lockstep(45.0, on_control=lambda r: lines.append(r.status_line()))
    assert not rt.map.snapshot().objects, "the dark box was mapped: this test needs one the cameras cannot see"
    assert rt.world.collisions == [], f"{len(rt.world.collisions)} contacts with the dark box"
    assert min(log.min_distance_m) > 0.0
    assert rt.run_state in (RunState.FINISHED, RunState.RUNNING), rt.status_line()  # went round, or stopped
    told = [line for line in lines if "unknown space ahead" in line]
    assert told, "the status line never said why the robot slowed"
    assert rt.problems.count(ProblemKind.UNKNOWN_SPACE) >= 1
    assert "unknown space ahead" in summary_line(rt.problems.counts())
    assert rt.closed_loop.unknown_slowed_steps > 0


@pytest.mark.slow
def test_with_unknown_space_free_the_base_drives_into_the_box_that_returns_no_depth():
    """The paper's map, for contrast: the failure the default exists to prevent (so the test above can fail)."""
    scene = Scene((DARK,), robot_start=(0.0, 0.0, 0.0))
    sequence = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=5.0, y=0.0), timeout_s=12.0)])
    config = RuntimeConfig(map_kind="object", mapping=replace(MappingParams(), unknown_space="free"))
    rt = Runtime(config, scene=scene, sequence=sequence)
    rt.run_lockstep(12.0)
    assert rt.world is not None and rt.world.collisions, "the base should have met the box it cannot see"
