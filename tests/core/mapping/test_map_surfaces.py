"""Mapped surfaces where they are (docs/decisions.md, "Mapped surfaces where they are"): the distances the
controller reads near a seen face are the face's own, not a voxel-rounding or a noise-fattened box nearer."""

import numpy as np
import pytest

from core.mapping import ObjectMapper
from core.mapping.box_fit import fit_upright_box
from core.mapping.local_edf import EDFGrid, box_field, column_field, mark_columns, signed_distance, window_axes
from core.mapping.submap import ObjectSubmap
from core.mapping.tracked_object import noise_weight
from core.params import MappingParams, SensorParams
from core.robot.model import READY_Q, RobotModel
from core.scene import Box
from core.sim.ground_truth import box_signed_distance, scene_signed_distance
from core.types import LocalEDF
from tests.core.mapping.rendered_views import View

WINDOW = (4.0, 4.0, 1.4)


@pytest.mark.parametrize("yaw", [0.0, 0.5])
def test_box_field_is_the_analytic_distance(yaw):
    box = Box("b", (1.03, 0.27, 0.3), (0.6, 0.5, 0.6), yaw)
    grid = EDFGrid.around(np.zeros(2), WINDOW, 0.1, pad_m=0.5)
    axes = window_axes(grid)
    values = box_field(axes, [(box.pose(), np.array(box.size))], cutoff=1.8)
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    np.testing.assert_allclose(values, np.clip(box_signed_distance(nodes, box), -1.8, 1.8), atol=1e-9)


@pytest.mark.parametrize("x_wall", [1.0, 1.03, 1.07])
def test_column_field_reads_a_seen_wall_to_a_centimetre_where_the_transform_reads_a_voxel_nearer(x_wall):
    """A wall seen from the side: its surface points (5 cm apart) wherever the 10 cm nodes fall."""
    y, z = np.meshgrid(np.arange(-1.5, 1.5, 0.05), np.arange(0.05, 0.8, 0.05), indexing="ij")
    wall = np.stack([np.full(y.size, x_wall), y.ravel(), z.ravel()], axis=1)
    grid = EDFGrid.around(np.zeros(2), WINDOW, 0.1, pad_m=0.5)
    edf_values = column_field(grid, wall, cutoff=1.8)
    edf = LocalEDF(grid.window_origin, 0.1, edf_values, 1.8)
    d = np.random.default_rng(0).uniform(0.05, 0.5, 300)
    p = np.stack([x_wall - d, np.random.default_rng(1).uniform(-1.0, 1.0, 300), np.full(300, 0.4)], axis=1)
    err = edf.distance(p) - d
    assert np.median(np.abs(err)) < 0.005 and np.max(np.abs(err)) < 0.035  # the worst just off a one-node sheet
    # node to node (what the EDF was): up to a voxel nearer
    occupied = grid.empty()
    mark_columns(grid, occupied, wall)
    old = LocalEDF(grid.window_origin, 0.1, signed_distance(occupied, 0.1, 1.8)[grid.window], 1.8)
    assert np.median(old.distance(p) - d) < -0.015
    assert abs(edf.distance(np.array([x_wall, 0.0, 0.4]))) < 0.035  # the zero level on the wall


def test_box_fit_settles_on_the_faces_of_noisy_points():
    """Depth noise spreads a face's points about it: the box fits the faces, not the outermost points."""
    rng = np.random.default_rng(2)
    box = Box("b", (0.0, 0.0, 0.3), (0.6, 0.6, 0.6))
    u, v = np.meshgrid(np.arange(-0.3, 0.3, 0.05), np.arange(0.0, 0.6, 0.05), indexing="ij")
    faces = []
    for axis in (0, 1):
        for side in (-1, 1):
            f = np.zeros((u.size, 3))
            f[:, axis], f[:, 1 - axis], f[:, 2] = side * 0.3 + rng.normal(0.0, 0.03, u.size), u.ravel(), v.ravel()
            faces.append(f)
    noisy = np.concatenate(faces)  # each face's points spread 3 cm along its normal
    fit = fit_upright_box(noisy, floor_z=0.0, floor_snap_m=0.15, yaw=0.0)
    assert np.all(np.abs(fit.extent[:2] - np.array(box.size[:2])) < 0.03)
    assert np.max(noisy[:, 0]) - np.min(noisy[:, 0]) > 0.7  # min/max would have been 10 cm too fat


def test_a_box_seen_through_noisy_depth_reads_true_distances_off_its_seen_faces():
    box = Box("b", (2.0, 0.3, 0.3), (0.6, 0.6, 0.6), 0.35)
    q = READY_Q.copy()
    robot = RobotModel()
    view = View(robot, (box,), q=q, sensor=SensorParams())
    mapper = ObjectMapper(robot, MappingParams())
    for k in range(15):
        q[2] = 0.3 * np.sin(k / 3)
        view.world.set_robot(q)
        mapper.integrate(view.observe())
    edf = mapper.local_edf(np.zeros(2))
    rng = np.random.default_rng(3)
    c, s = np.cos(box.yaw), np.sin(box.yaw)
    front = np.array([-c, -s, 0.0])  # the face towards the robot
    along = rng.uniform(-0.25, 0.25, 400)
    face = np.array(box.position) + 0.3 * front + np.outer(along, [-s, c, 0.0]) + np.outer(
        rng.uniform(-0.25, 0.25, 400), [0, 0, 1])
    d = rng.uniform(0.05, 0.5, 400)
    p = face + np.outer(d, front)
    err = edf.distance(p) - scene_signed_distance(p, (box,))
    view.close()
    assert np.median(np.abs(err)) <= 0.02 and np.percentile(np.abs(err), 95) <= 0.05, np.percentile(err, [5, 50, 95])


def test_near_returns_outweigh_far_ones_in_the_surface_voxels():
    """A wall at x = 2.01 seen from 3 m (σ = 0.005 z² = 4.5 cm, wider than a voxel) and then from 1 m (5 mm):
    each point weighs its inverse noise variance (`noise_weight`), so the centroid of the voxel the wall lies in
    is the near returns' (to a millimetre or two, median), where the plain mean was pulled towards the voxel's middle by
    the far returns spread across it. (Voxels only the far view's noise reached keep that noise: the weights
    cannot move them; `docs/decisions.md`, "Surface voxels fused by their depth noise".)"""
    rng = np.random.default_rng(3)
    n = 4000
    wall = np.column_stack([np.full(n, 2.01), rng.uniform(-0.5, 0.5, n), rng.uniform(0.1, 0.7, n)])
    far = wall + np.column_stack([rng.normal(0.0, 0.005 * 3.0**2, n), np.zeros((n, 2))])
    near = wall + np.column_stack([rng.normal(0.0, 0.005, n), np.zeros((n, 2))])
    weighted, plain = ObjectSubmap(0.05), ObjectSubmap(0.05)
    for points, camera in ((far, np.array([-1.0, 0.0, 0.5])), (near, np.array([1.0, 0.0, 0.5]))):
        weighted.integrate(points, noise_weight(points, camera))
        plain.integrate(points)
    np.testing.assert_allclose(noise_weight(np.array([[3.0, 0, 0], [1.0, 0, 0]]), np.zeros(3)), [1 / 81, 1.0])
    on_wall = np.floor(weighted.points[:, 0] / 0.05) == 40  # the voxels 2.00–2.05 m the wall lies in
    assert np.all(np.floor(plain.points[on_wall, 0] / 0.05) == 40)
    off_weighted = np.median(np.abs(weighted.points[on_wall, 0] - 2.01))
    off_plain = np.median(np.abs(plain.points[on_wall, 0] - 2.01))
    assert off_weighted < 0.002 and off_plain > 2 * off_weighted, (off_weighted, off_plain)
    np.testing.assert_allclose(plain.counts, weighted.counts)  # the counts (support, carving) are unchanged
