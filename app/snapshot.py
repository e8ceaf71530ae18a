"""What the runtime publishes to its subscribers (the UI, the bridge, recorders): one frozen value."""

from __future__ import annotations

from dataclasses import dataclass, field

from core.sim.scene import Box
from core.types import RobotState


@dataclass(frozen=True)
class Snapshot:
    """The studio's view of the world at sim time `state.t`."""

    seq: int
    wall_time: float
    state: RobotState
    boxes: tuple[Box, ...] = ()
    running: bool = False
    status: str = ""
    timings_ms: dict[str, float] = field(default_factory=dict)
