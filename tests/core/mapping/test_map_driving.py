"""The object map while the robot drives: rows of touching boxes joined at a corner (the paper's aisle)
are neither removed nor turned into boxes over the corridor, and the EDF the controller gets stays
within a voxel or two of the truth; a box pushed against another leaves no phantom where it was."""

import math

import numpy as np
import pytest

from core.mapping import ObjectMapper
from core.robot.model import READY_Q
from core.scene import Box, aisle_scene
from core.sim.ground_truth import ground_truth_edf, scene_signed_distance
from tests.core.mapping.rendered_views import View

NOISE = 0.005


def _drive(start: tuple[float, float], corners: list[tuple[float, float]], step_m: float):
    """(x, y, yaw) every `step_m` along the polyline start → corners, facing the way of travel."""
    pos = np.array(start)
    for c in corners:
        c = np.array(c)
        d = c - pos
        n = int(np.linalg.norm(d) / step_m)
        yaw = math.atan2(d[1], d[0])
        for i in range(n):
            yield (*(pos + d * i / n), yaw)
        pos = c


@pytest.mark.slow
def test_driving_round_an_aisle_corner_keeps_the_rows_and_an_edf_true_to_a_voxel_or_two(robot, params):
    scene = aisle_scene()
    view = View(robot, scene.boxes, noise_std_m=NOISE)
    mapper = ObjectMapper(robot, params)
    x, y = 3.95, -2.45  # the corridor's centre line on the south and east sides
    errors = []
    for k, (px, py, yaw) in enumerate(_drive((-1.0, y), [(x, y), (x, 0.5)], 0.05)):  # 10 Hz at 0.5 m/s
        q = READY_Q.copy()
        q[:3] = px, py, yaw
        view.world.set_robot(q)
        mapper.integrate(view.observe())
        if k >= 30 and k % 5 == 0:  # once the walls beside the robot were seen ahead of it
            edf = mapper.local_edf(q[:2])
            truth = ground_truth_edf(scene.boxes, q[:2], params.edf_window_m, params.edf_voxel_m,
                                     params.theta_cutoff_m)
            spheres = robot.sphere_centres(q)
            errors.append(edf.distance(spheres) - truth.distance(spheres))
    errors = np.concatenate(errors)
    assert mapper.removed_ids == mapper.merged_ids  # nothing removed as changed: only duplicates merged
    merges = mapper.snapshot().merged_into  # each merged object → the live object its surface went into
    assert mapper.merged_ids and set(merges) == set(mapper.merged_ids)
    assert set(merges.values()) <= set(mapper.objects)
    assert errors.max() <= 0.5 * params.edf_voxel_m  # never farther from an obstacle than it is
    assert errors.min() >= -2.5 * params.edf_voxel_m  # and conservative by at most two voxels or so
    # every mapped surface voxel lies on a box, and the walls around the corner are not one box
    pts = mapper.occupied_points()
    assert np.percentile(scene_signed_distance(pts, scene.boxes), 99) < 0.1
    assert any(not o.box_like for o in mapper.objects.values())
    view.close()


def test_a_box_pushed_against_another_leaves_no_phantom_where_it_was(robot, params):
    a, b = Box("a", (1.9, -0.45, 0.25), (0.5, 0.5, 0.5)), Box("b", (1.9, 0.45, 0.25), (0.5, 0.5, 0.5))
    view = View(robot, (a, b), noise_std_m=NOISE)
    mapper = ObjectMapper(robot, params)
    for _ in range(10):
        mapper.integrate(view.observe())
    ids = set(mapper.objects)
    assert len(ids) == 2
    moved = Box("b", (1.9, 0.06, 0.25), (0.5, 0.5, 0.5))  # 39 cm, to 1 cm from a: one segment now
    view.world.move_box("b", moved.position)
    for _ in range(15):
        mapper.integrate(view.observe())
    pts = mapper.occupied_points()
    assert np.max(scene_signed_distance(pts, (a, moved))) < 0.1  # nothing left where b stood
    edf = mapper.local_edf(np.zeros(2))
    assert edf.distance(np.array([[1.9, 0.6, 0.25]]))[0] > 0.2  # its old centre is free in the EDF
    assert set(mapper.objects) <= ids  # the two boxes are mapped by the objects they had
    view.close()
