"""The interface the runtime drives every map through: the object-level map and the voxel baseline.

The studio runtime calls `integrate` at 5–10 Hz and `local_edf` + `occupied_points` at 10 Hz, from
different threads but never concurrently (it holds a lock).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from core.types import LocalEDF, ObjectMapSnapshot, Observation

TIMING_KEYS: tuple[str, ...] = ("points", "segmentation", "association", "registration", "consistency", "edf")
"""Stages reported in `timings_ms` (ms of the last `integrate`; 'edf' of the last `local_edf`)."""


class WorldMap(Protocol):
    """A map built from depth frames that the controller sees through a signed `LocalEDF`."""

    @property
    def timings_ms(self) -> dict[str, float]:
        """Milliseconds of the stages of the latest integration, by stage name."""
        ...

    def integrate(self, obs: Observation) -> None:
        """Fuse every depth frame of `obs`; `obs.state` gives the robot's pose for the self-filter."""
        ...

    def snapshot(self) -> ObjectMapSnapshot:
        """The objects now (the voxel map has none: `objects=()`, `removed_ids=()`)."""
        ...

    def local_edf(self, centre_xy: np.ndarray) -> LocalEDF:
        """Signed EDF in the window around `centre_xy`, `theta_cutoff` outside it."""
        ...

    def occupied_points(self) -> np.ndarray:
        """Occupied voxel centres (P×3) of live objects, for 2D path planning and display."""
        ...
