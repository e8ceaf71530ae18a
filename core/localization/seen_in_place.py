"""Whether a frame sees an object's reference surface where the reference has it: the other direction of the
residual test (reference → frame, by the depth at each reference point's pixel).

The residual test (`Localizer._object_residuals`) reads the frame's points near an object against its surface, and
a surface the reference does not hold yet lies near some object too: on E4's aisle (lap 3, localization on) the
island's outer south face, never mapped before, sat 0.16 and 0.12 m (median) from the two objects holding the
island's corner and its inner faces, so both read as off although both were where the frame saw them; the frames
that showed the face were held for verdicts that kept refusing them, the localizer got lost, the search fit the frame
onto the island's inner corner 0.6 m away, and the run faulted (docs/decisions.md). An object is seen in place when
most of its reference points that the frame can judge are hit at their depth: confirmed when the frame's depth at the
point's pixel is within `confirm_m` of the point's; displaced when it is deeper (seen through: the surface is not
there) or nearer by less than `occluder_m` (the surface moved towards the camera); anything nearer than that is
an occluder and no evidence either way, and a pixel without a return says nothing.
"""

from __future__ import annotations

import numpy as np

from core.types import DepthFrame


def seen_in_place(points_world: np.ndarray, frame: DepthFrame, T_world_camera: np.ndarray, confirm_m: float,
                  occluder_m: float, min_points: int) -> bool:
    """Whether at least half of the points (an object's reference surface, P×3, world) that the frame, taken at
    T_world_camera, can judge are confirmed at their depth; False when fewer than `min_points` can be judged."""
    T = np.linalg.inv(T_world_camera)
    c = np.asarray(points_world, float) @ T[:3, :3].T + T[:3, 3]
    depth = np.asarray(frame.depth)
    h, w = depth.shape
    z = c[:, 2]
    front = z > 0.1
    zs = np.where(front, z, 1.0)
    u = np.floor(frame.K[0, 0] * c[:, 0] / zs + frame.K[0, 2]).astype(int)
    v = np.floor(frame.K[1, 1] * c[:, 1] / zs + frame.K[1, 2]).astype(int)
    inside = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    seen = depth[v[inside], u[inside]]
    z = z[inside]
    returned = np.isfinite(seen) & (seen > 0.0) & (seen < frame.range_m)
    r = seen[returned] - z[returned]
    confirmed = np.abs(r) <= confirm_m
    displaced = (r > confirm_m) | ((r < -confirm_m) & (r >= -occluder_m))
    judged = int(np.sum(confirmed) + np.sum(displaced))
    return judged >= min_points and 2 * int(np.sum(confirmed)) >= judged
