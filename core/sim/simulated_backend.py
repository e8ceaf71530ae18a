"""`SimulatedBackend`: a robot backend that is a simulation, whose world the runtime may read and edit.

A backend declares it with `BackendAbilities.simulated`; `is_simulated` then gives the runtime its
`SimWorld` (scene edits, ground-truth distances and collisions, the ground-truth map) and its sensor model.
`SimRobot` is the one there is.
"""

from __future__ import annotations

from typing import Protocol, TypeGuard

from core.params import SensorParams
from core.sim.world import SimWorld
from core.types import RobotBackend


class SimulatedBackend(RobotBackend, Protocol):
    """A simulated robot: its world, and the sensor model it perceives through."""

    @property
    def world(self) -> SimWorld:
        """The simulated world (the truth the robot does not know)."""
        ...

    def set_sensor(self, sensor: SensorParams) -> None:
        """Perceive through `sensor` from now on."""
        ...


def is_simulated(backend: RobotBackend) -> TypeGuard[SimulatedBackend]:
    """Whether `backend` is a simulation (as it declares): then it has a `world` and `set_sensor`."""
    return backend.abilities.simulated
