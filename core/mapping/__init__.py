"""Object-level mapping (POCD), the voxel-level baseline map and the local EDF (docs/method.md).

`ObjectMapper` and `VoxelMap` implement `WorldMap`; both are built as `Cls(robot, params)`. Each takes
`integrate(observation)` and answers `local_edf(centre_xy) -> LocalEDF` (signed distances for the controller),
`occupied_points()` (for the planner) and `snapshot() -> ObjectMapSnapshot`.
"""

from core.mapping.depth_points import frame_points, unproject
from core.mapping.object_mapper import ObjectMapper
from core.mapping.voxel_map import VoxelMap
from core.mapping.world_map import WorldMap
from core.params import MappingParams
from core.types import DepthFrame, LocalEDF, MappedObject, ObjectMapSnapshot, Observation, Posterior

__all__ = ["DepthFrame", "LocalEDF", "MappedObject", "MappingParams", "ObjectMapSnapshot", "ObjectMapper",
           "Observation", "Posterior", "VoxelMap", "WorldMap", "frame_points", "unproject"]
