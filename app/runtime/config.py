"""`RuntimeConfig`: how a run is set up (scene, sequence, map and constraint kind, pace, modelled delays,
tunables), and the default scene and sequence. Its own module, below everything else in `app.runtime`, so
that the closed loop can read its configuration without importing the runtime that owns it."""

from __future__ import annotations

import typing
from dataclasses import dataclass, field, replace
from pathlib import Path

from app.map_kind import MAP_KINDS, MapKind
from core.params import (
    ConstraintKind,
    HTMPCParams,
    LocalizationParams,
    MappingParams,
    RobotParams,
    SequencerParams,
    SimParams,
)

__all__ = ["CONSTRAINT_KINDS", "DEFAULT_SCENE", "DEFAULT_SEQUENCE", "ROOT", "RuntimeConfig"]

ROOT = Path(__file__).parents[2]
DEFAULT_SCENE = ROOT / "core" / "scenes" / "default.yaml"
DEFAULT_SEQUENCE = ROOT / "tasks" / "examples" / "two_pickups.yaml"
CONSTRAINT_KINDS: tuple[ConstraintKind, ...] = typing.get_args(ConstraintKind)
SPEED_RANGE = (0.05, 20.0)
"""Live mode: the sim seconds per wall second a run accepts (the bridge's API checks the same range)."""


@dataclass(frozen=True)
class RuntimeConfig:
    """How to run: scene, sequence, map and constraint kind, pace, modelled delays, tunables."""

    scene: Path | None = DEFAULT_SCENE
    sequence: Path | None = DEFAULT_SEQUENCE
    map_kind: MapKind = "object"
    speed: float = 1.0
    """Live mode: sim seconds per wall second."""
    perception_delay_s: float = 0.0
    actuation_delay_s: float = 0.0
    publish_hz: float = 20.0
    map_process: bool = True
    """Live mode: run the object and voxel maps in a process of their own (keeps the I/O loops on time)."""
    live_niceness: int | None = -10
    """Live mode: the niceness its threads ask for (lower runs first, as robot control stacks do; needs root
    or CAP_SYS_NICE, else they stay at normal priority: `app/thread_priority.py`); None leaves priorities alone."""
    seed: int = 0
    htmpc: HTMPCParams = field(default_factory=HTMPCParams)
    mapping: MappingParams = field(default_factory=MappingParams)
    sequencer: SequencerParams = field(default_factory=SequencerParams)
    sim: SimParams = field(default_factory=SimParams)
    robot: RobotParams = field(default_factory=RobotParams)
    localization: LocalizationParams = field(default_factory=LocalizationParams)

    def __post_init__(self) -> None:
        if self.map_kind not in MAP_KINDS:
            raise ValueError(f"map_kind must be one of {MAP_KINDS}, got {self.map_kind!r}")
        if not (SPEED_RANGE[0] <= self.speed <= SPEED_RANGE[1]):
            raise ValueError(f"speed must be within {SPEED_RANGE[0]}–{SPEED_RANGE[1]:g}, got {self.speed}")

    @property
    def constraint(self) -> ConstraintKind:
        """The controller's constraint kind (`HTMPCParams.constraint`)."""
        return self.htmpc.constraint

    def configured(self, map_kind: MapKind | None = None, constraint: ConstraintKind | None = None) -> RuntimeConfig:
        """This configuration with another map kind and/or constraint kind (None: unchanged), validated."""
        htmpc = self.htmpc if constraint is None else replace(self.htmpc, constraint=constraint)
        return replace(self, map_kind=map_kind or self.map_kind, htmpc=htmpc)

