"""Segmentation: two boxes that a thin stray stroke of returns joins are two observations, never one object
(issue 26's merged phantom: box_a, box_c and a stroke between them were mapped as one point-cloud object)."""

import numpy as np

from core.mapping.segmentation import segment, voxelise
from core.mapping.tracked_object import TrackedObject
from core.params import MappingParams


def _face(x: float, y0: float) -> np.ndarray:
    """The points of a 0.6 × 0.55 m face at x, from y0 along y (2 cm apart, as a depth camera at 2 m)."""
    y, z = np.meshgrid(np.arange(0.0, 0.6, 0.02), np.arange(0.05, 0.6, 0.02), indexing="ij")
    return np.stack([np.full(y.size, x), y.ravel() + y0, z.ravel()], axis=1)


def test_two_boxes_joined_by_a_stroke_are_two_segments_and_two_objects():
    params = MappingParams()
    a, c = _face(2.0, 1.0), _face(2.0, 2.2)  # 0.6 m apart
    stroke = np.stack([np.full(40, 2.0), np.linspace(1.6, 2.2, 40), np.full(40, 0.3)], axis=1)
    segments = segment(voxelise(np.concatenate([a, c, stroke]), params.voxel_m), params.min_segment_voxels)
    assert len(segments) == 2
    for seg, face in zip(sorted(segments, key=lambda s: s.lower[1]), (a, c), strict=True):
        assert seg.lower[1] >= face[:, 1].min() - 0.1 and seg.upper[1] <= face[:, 1].max() + 0.1  # + a stroke voxel
        obj = TrackedObject(1, seg.points, params.voxel_m, params.prior(), params.floor_snap_m)
        assert obj.extent[1] < 0.75  # a box's face, not both and the gap
    # without the stroke, and a face alone, nothing changes
    assert len(segment(voxelise(np.concatenate([a, c]), params.voxel_m), params.min_segment_voxels)) == 2
    alone = segment(voxelise(a, params.voxel_m), params.min_segment_voxels)
    assert len(alone) == 1 and len(alone[0].points) == len(voxelise(a, params.voxel_m).keys)


def test_touching_boxes_stay_one_segment():
    """Faces that touch along a wide seam (not a stroke) stay together: association shares them later."""
    params = MappingParams()
    joined = np.concatenate([_face(2.0, 1.0), _face(2.0, 1.6)])
    assert len(segment(voxelise(joined, params.voxel_m), params.min_segment_voxels)) == 1
