"""Object-level mapping (POCD), the voxel-level baseline map and the local EDF (docs/method.md).

`ObjectMapper` and `VoxelMap` implement `WorldMap`; both are built as `Cls(robot, params)`.
"""

from core.mapping.depth_points import frame_points, unproject
from core.mapping.object_mapper import ObjectMapper
from core.mapping.voxel_map import VoxelMap
from core.mapping.world_map import WorldMap

__all__ = ["ObjectMapper", "VoxelMap", "WorldMap", "frame_points", "unproject"]
