"""Unknown space: floor the cameras should have seen and did not (docs/method.md, "Unknown space is not free").

The paper's map, like ours, takes a pixel with no return as no evidence: right for clearing an object, wrong
for driving. A surface that never returns depth (black, glossy, glass) is never mapped, so its EDF reads the
cutoff and a goal behind it drives the base into it. A depth camera looking down at the floor does see it,
indirectly: a ray that should meet the floor within range and returns nothing met something on the way.

`UnknownFloor` keeps that evidence on floor cells (`unknown_cell_m`): each frame adds to a cell the number of
rays aimed at it that returned nothing, less those that returned something (the floor, or the top of an
ordinary box in front of it: a surface that answers); a cell whose sum reaches `unknown_evidence_rays` is
unknown, and floor seen there takes it back (the sum is kept within ± `unknown_evidence_max_rays`, and cells
at or below 0 are forgotten). A dark box's shadow gets there in one frame, every ray missing; the 2 % random
dropouts, at 5 rays a cell 2.5 m away, almost never (a rule of 3 misses in one frame marked cells at random
about twice a minute, and a pick in the aisle laps timed out 10° short beside one). A dark box leaves the
floor cells behind its face unknown, from the face itself on, while the floor before it stays seen. A ray
that meets the robot's own body (its collision spheres and base boxes, `self_filter.RobotBody`) is no
evidence either way: the arm reaching down in front of the base camera is nearer than its near clip and
reads 0, which marked the floor of a pick's far side unknown (the aisle laps' stop A: 400 cells).

`unknown_columns` turns the cells into a signed distance to columns from the floor up to `unknown_height_m`
on a `LocalEDF`'s lattice, so that the map can hand them to the controller inside its field.
"""

from __future__ import annotations

import math

import numpy as np

from core.mapping.depth_points import pixel_rays
from core.mapping.local_edf import signed_distance
from core.mapping.self_filter import RobotBody
from core.params import MappingParams
from core.types import DepthFrame, LocalEDF, UnknownSpace

PIXEL_STRIDE = 2
"""Every second pixel in u and v, as the map's points (`MappingParams.pixel_stride`)."""
KEY_BITS = 24
KEY_OFFSET = 1 << 23
"""A cell (i, j) is the key (i + KEY_OFFSET) << KEY_BITS | (j + KEY_OFFSET): ±800 km of 0.1 m cells."""


class UnknownFloor:
    """The floor cells with evidence of no return: sorted packed integer keys of (i, j) = round(xy / cell) and
    their evidence (rays)."""

    def __init__(self, params: MappingParams) -> None:
        self.params = params
        self._cells = np.zeros(0, dtype=np.int64)
        self._evidence = np.zeros(0, dtype=np.int32)

    @property
    def keys(self) -> np.ndarray:
        """The unknown cells' keys (sorted)."""
        return self._cells[self._evidence >= self.params.unknown_evidence_rays]

    def integrate(self, frame: DepthFrame, body: RobotBody | None = None) -> None:
        """Mark the cells whose expected floor rays returned nothing; clear those where the floor was seen. Rays
        that meet `body` (the robot at the frame's exposure) are left out."""
        p = self.params
        if frame.camera not in p.unknown_cameras:
            return
        rays, v, u = pixel_rays(frame.K, frame.depth.shape, PIXEL_STRIDE)
        R, t = frame.T_world_camera[:3, :3].astype(np.float32), frame.T_world_camera[:3, 3]
        if t[2] <= 0.0:
            return
        dz = rays @ R[2]  # world z of each ray per metre of planar depth
        z = frame.depth[v, u]
        expected = np.divide(-t[2], dz, out=np.full(len(dz), np.inf, dtype=np.float32), where=dz < 0.0)
        aimed = (expected >= p.unknown_floor_min_depth_m) & (expected <= min(p.unknown_floor_range_m, frame.range_m))
        if body is not None:
            idx = np.nonzero(aimed)[0]
            aimed[idx[meets_body(t, rays[idx] @ R.T, expected[idx], body)]] = False
        floor_xy = t[:2] + (rays[aimed] @ R[:2].T) * expected[aimed, None]  # where the floor should have been
        returned = z > 0.0
        on_floor = t[2] + dz[returned] * z[returned] < p.floor_height_m
        floor_hits = t[:2] + (rays[returned][on_floor] @ R[:2].T) * z[returned][on_floor, None]
        self._update(self._key(floor_xy), z[aimed] <= 0.0, self._key(floor_hits))

    def _key(self, xy: np.ndarray) -> np.ndarray:
        ij = np.rint(xy / self.params.unknown_cell_m).astype(np.int64) + KEY_OFFSET
        return (ij[:, 0] << KEY_BITS) + ij[:, 1]

    def _update(self, aimed: np.ndarray, missed: np.ndarray, hits: np.ndarray) -> None:
        """`aimed`: the cells of the rays aimed at the floor, `missed` which of them returned nothing; `hits`:
        the cells of floor points seen."""
        p = self.params
        keys, index = np.unique(np.concatenate([aimed, hits]), return_inverse=True)
        n_aimed = np.bincount(index[:len(aimed)], minlength=len(keys))
        n_miss = np.bincount(index[:len(aimed)][missed], minlength=len(keys))
        n_hit = np.bincount(index[len(aimed):], minlength=len(keys))
        delta = n_miss - np.maximum(n_aimed - n_miss, n_hit)  # an aimed ray that saw the floor is one of the hits
        cells = np.union1d(self._cells, keys)
        evidence = np.zeros(len(cells), dtype=np.int32)
        evidence[np.searchsorted(cells, self._cells)] = self._evidence
        evidence[np.searchsorted(cells, keys)] += delta.astype(np.int32)
        np.clip(evidence, None, p.unknown_evidence_max_rays, out=evidence)
        keep = evidence > 0
        self._cells, self._evidence = cells[keep], evidence[keep]

    def centres(self) -> np.ndarray:
        """World x-y of the unknown cells' centres (K×2)."""
        i, j = (self.keys >> KEY_BITS) - KEY_OFFSET, (self.keys & ((1 << KEY_BITS) - 1)) - KEY_OFFSET
        return np.column_stack([i, j]).astype(float) * self.params.unknown_cell_m

    def space(self) -> UnknownSpace:
        """The unknown cells as the narrow type the planner and the operator's notice read."""
        p = self.params
        return UnknownSpace(centres=self.centres(), cell_m=p.unknown_cell_m, height_m=p.unknown_height_m)


def meets_body(origin: np.ndarray, dirs: np.ndarray, depth: np.ndarray, body: RobotBody) -> np.ndarray:
    """Do the rays origin + s · dirs (N×3, world, per metre of planar depth) meet the body before s = depth?"""
    d = dirs.astype(float)
    w = body.centres - origin  # M×3
    along = d @ w.T  # N×M: s · |d|² at the closest approach
    dd = np.einsum("ij,ij->i", d, d)[:, None]
    dist2 = np.einsum("ij,ij->i", w, w)[None, :] - along**2 / dd
    hit = ((dist2 <= body.radii**2) & (along > 0.0) & (along < depth[:, None] * dd)).any(axis=1)
    x, y, yaw = body.base_pose
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world → base frame
    o = rot @ (origin - np.array([x, y, 0.0]))
    local = d @ rot.T
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo, hi in zip(body.box_lo, body.box_hi, strict=True):
            t1, t2 = (lo - o) / local, (hi - o) / local
            # a ray parallel to a slab is inside it for every s or for none
            t1 = np.where(local == 0.0, np.where((o >= lo) & (o <= hi), -np.inf, np.inf), t1)
            t2 = np.where(local == 0.0, np.where((o >= lo) & (o <= hi), np.inf, -np.inf), t2)
            near, far = np.minimum(t1, t2).max(axis=1), np.maximum(t1, t2).min(axis=1)
            hit |= (near <= far) & (far > 0.0) & (near < depth)
    return hit


def unknown_columns(edf: LocalEDF, space: UnknownSpace) -> LocalEDF:
    """`edf` with the unknown columns added as obstacles (the signed field of the union: the minimum), and
    `space` attached. The columns' 2D signed distance is computed on the field's lattice grown by the cutoff
    (cells just outside the window shape the field near its edge), then lifted to 3D: above a column's top
    the distance is to its top face."""
    pad = int(math.ceil(edf.cutoff / edf.voxel))
    nx, ny, nz = edf.values.shape
    origin = edf.origin[:2] - pad * edf.voxel
    near = np.all((space.centres >= origin - space.cell_m) &
                  (space.centres <= origin + edf.voxel * np.array([nx + 2 * pad, ny + 2 * pad]) + space.cell_m), axis=1)
    if not near.any():
        return LocalEDF(edf.origin, edf.voxel, edf.values, edf.cutoff, unknown=space)
    occupied = np.zeros((nx + 2 * pad, ny + 2 * pad), dtype=bool)
    _mark_cells(occupied, origin, edf.voxel, space.centres[near], space.cell_m)
    d2 = signed_distance(occupied, edf.voxel, edf.cutoff)[pad:pad + nx, pad:pad + ny, None]
    above = edf.origin[2] + edf.voxel * np.arange(nz) - space.height_m  # > 0 above the columns' top
    d3 = np.where(d2 > 0.0, np.sqrt(d2**2 + np.maximum(above, 0.0) ** 2), np.maximum(d2, above))
    values = np.clip(np.minimum(edf.values, d3), -edf.cutoff, edf.cutoff)
    return LocalEDF(edf.origin, edf.voxel, np.ascontiguousarray(values), edf.cutoff, unknown=space)


def _mark_cells(occupied: np.ndarray, origin: np.ndarray, voxel: float, centres: np.ndarray, cell_m: float) -> None:
    """Set the lattice nodes inside each square cell (half width at least half a node, so that every cell
    takes its nearest nodes, as `local_edf.mark_boxes` does for thin boxes)."""
    half = max(cell_m, voxel) / 2 + 1e-9
    lo = np.ceil((centres - half - origin) / voxel).astype(int)
    hi = np.floor((centres + half - origin) / voxel).astype(int)
    span = int(np.max(hi - lo)) + 1
    for di in range(span):
        for dj in range(span):
            i, j = lo[:, 0] + di, lo[:, 1] + dj
            ok = (i <= hi[:, 0]) & (j <= hi[:, 1]) & (i >= 0) & (j >= 0) & (i < occupied.shape[0]) & \
                (j < occupied.shape[1])
            occupied[i[ok], j[ok]] = True
