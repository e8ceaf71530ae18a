"""Checks the reaction tests share (the embedded run and the run through the bridge), read again from the stamps
independently of `bench/reaction_chain.py`."""

from __future__ import annotations

import numpy as np

from app.runtime.stage_stamps import CommandStamp, ControlStamp, StageStamps
from bench.reaction_chain import DROP_MPS, Placement


def first_slowed(stamps: StageStamps, placement: Placement) -> CommandStamp:
    """The first command after the placement slowed by `DROP_MPS` towards the box."""
    towards = np.asarray(placement.towards)
    for command in stamps.commands:
        if command.wall > placement.wall and np.dot(command.base_v, towards) <= placement.v_before_mps - DROP_MPS:
            return command
    raise AssertionError("no command slowed")


def step_that_held_the_box(stamps: StageStamps, placement: Placement, command: CommandStamp,
                           voxel_m: float) -> ControlStamp:
    """The control step whose plan `command` came from, checked to be solved after the placement on an EDF holding
    the box (its face within one voxel)."""
    step = next(s for s in stamps.controls if s.plan is command.plan)
    assert step.wall_wake > placement.wall  # solved after the box appeared …
    assert step.edf is not None and float(step.edf.distance(placement.face)) <= voxel_m  # … with the box in it
    return step

