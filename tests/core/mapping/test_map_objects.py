"""ObjectMapper on rendered MuJoCo depth frames: boxes found with their pose and extent, new boxes
appear at once, the robot and the floor are not objects, the EDF matches the true box."""

from dataclasses import replace

import numpy as np
import pytest

from core.mapping import ObjectMapper
from core.mapping.depth_points import frame_points, unproject
from core.mapping.scene_points import ScenePoints
from core.mapping.segmentation import segment, voxelise
from core.mapping.self_filter import SelfFilter
from core.params import SensorParams
from core.scene import Box
from core.sim.ground_truth import box_signed_distance, ground_truth_edf
from core.types import ObjectStatus, Observation, RobotState
from tests.core.mapping.rendered_views import View, yaw_error, yaw_of


def _match(snapshot, box: Box):
    """The mapped object nearest to a box (centre distance in x-y)."""
    objs = list(snapshot.objects)
    d = [np.linalg.norm(o.pose[:2, 3] - np.array(box.position[:2])) for o in objs]
    return objs[int(np.argmin(d))]


def test_depth_points_lie_on_the_seen_box(robot):
    box = Box("a", (1.8, 0.0, 0.3), yaw=0.2)
    view = View(robot, (box,), cameras=("hand",))
    frame = view.frame_set()[0]
    pts = frame_points(frame, stride=2)
    assert len(pts) > 1000 and np.all(np.linalg.norm(pts - frame.T_world_camera[:3, 3], axis=1) <= 3.0 * 1.8)
    off_floor = pts[pts[:, 2] > 0.02]
    assert np.percentile(np.abs(box_signed_distance(off_floor, box)), 99) < 0.01
    short = unproject(frame.depth, frame.K, frame.T_world_camera, stride=1, range_m=1.5)
    depth_along_axis = (short - frame.T_world_camera[:3, 3]) @ frame.T_world_camera[:3, 2]
    assert depth_along_axis.max() <= 1.5 + 1e-6
    view.close()


@pytest.mark.parametrize(("sensor", "tol"), [(SensorParams.ideal(), 0.05),
                                            (replace(SensorParams.ideal(), depth_noise_m=0.003), 0.05),
                                            (SensorParams(), 0.07)], ids=["exact", "noise", "camera model"])
def test_boxes_in_view_found_with_pose_within_5cm_and_extent_within_tol(robot, params, sensor, tol):
    # with the camera model (depth std 0.005 z², 2.2 cm at the far box) a voxel of noise beyond a face may
    # widen the box: 7 cm there
    boxes = (Box("a", (1.8, -0.5, 0.3), yaw=0.3), Box("b", (2.1, 0.7, 0.4), size=(0.4, 0.5, 0.8), yaw=-0.2))
    view = View(robot, boxes, sensor=sensor)
    mapper = ObjectMapper(robot, params)
    for _ in range(5):
        mapper.integrate(view.observe())
    snap = mapper.snapshot()
    assert len(snap.objects) == 2 and snap.removed_ids == ()
    for box in boxes:
        obj = _match(snap, box)
        assert obj.status == ObjectStatus.ACTIVE
        assert np.linalg.norm(obj.pose[:3, 3] - np.array(box.position)) < 0.05
        assert yaw_error(yaw_of(obj.pose), box.yaw) < np.radians(5)
        # extent: compare sorted footprint sides (a box's axes are defined modulo 90°)
        assert np.all(np.abs(np.sort(obj.extent[:2]) - np.sort(box.size[:2])) < tol)
        assert abs(obj.extent[2] - box.size[2]) < 0.05
        assert obj.consistency > 0.66 and obj.observations >= 5
    view.close()


def test_a_new_box_appears_within_two_frames(robot, params):
    view = View(robot, (Box("a", (1.8, -0.5, 0.3)),), cameras=("hand",))
    mapper = ObjectMapper(robot, params)
    for _ in range(3):
        mapper.integrate(view.observe())
    assert len(mapper.snapshot().objects) == 1
    new = Box("new", (1.9, 0.6, 0.25), size=(0.5, 0.5, 0.5))
    view.world.add_box(new)
    mapper.integrate(view.observe())
    snap = mapper.snapshot()
    assert len(snap.objects) == 2  # the frame after the box was dropped in
    obj = _match(snap, new)
    assert np.linalg.norm(obj.pose[:2, 3] - np.array(new.position[:2])) < 0.15
    view.close()


def test_robot_and_floor_are_not_objects(robot, params):
    # the hand camera looks down at the robot's own base and arm (and the floor around them)
    q = np.array([0.0, 0.0, 0.0, 1.16, -0.45, 2.35, 0.42, 1.42, 4.05])
    view = View(robot, (), q=q)
    pts = frame_points(view.frame_set()[0], stride=2)
    on_robot = ~SelfFilter(robot).outside(pts, q) & (pts[:, 2] > 0.1)
    assert on_robot.sum() > 50  # the hand camera does see the robot
    mapper = ObjectMapper(robot, params)
    for _ in range(3):
        mapper.integrate(view.observe())
    assert mapper.snapshot().objects == ()
    assert len(mapper.occupied_points()) == 0
    view.close()


def test_no_part_of_the_robot_is_left_by_the_self_filter_in_random_configurations(robot, params):
    view = View(robot, ())
    points = ScenePoints(robot, params)
    rng = np.random.default_rng(0)
    clusters = []
    for _ in range(60):  # arm anywhere within its limits; the base corners and the shoulder were left before
        view.world.set_robot(robot.random_q(rng, base_span_m=0.0))
        obs = Observation(view.world.state(), view.frame_set(), None)
        for _, pts in points.each(obs, {}):
            clusters += segment(voxelise(pts, params.voxel_m), params.min_segment_voxels)
    assert not any(clusters)  # at most a few specks, never an object's worth
    view.close()


def test_the_self_filter_places_the_robot_where_it_was_when_the_frame_was_taken(robot, params):
    q = np.array([0.0, 0.0, 0.0, 1.16, -0.45, 2.35, 0.42, 1.42, 4.05])
    view = View(robot, (), q=q)
    (frame,) = view.frame_set()[:1]
    v = np.zeros(9)
    v[[0, 2, 3]] = 1.0, 0.75, 2.0  # base and arm at full speed, the state reported half a second after the
    later = RobotState(t=frame.t + 0.5, q=q + 0.5 * v, v=v)  # frame (a lag the spheres' slack cannot hide)
    points = ScenePoints(robot, params)
    (_, seen), = points.each(Observation(later, (frame,), None), {})
    expected = points.of_frame(frame, SelfFilter(robot).body(q))
    np.testing.assert_array_equal(seen, expected)
    unmoved = points.of_frame(frame, SelfFilter(robot).body(later.q))
    assert not np.array_equal(unmoved, expected)  # the spheres at the state's q would filter other points
    view.close()


def test_object_edf_matches_the_true_box_within_a_voxel(robot, params):
    box = Box("a", (1.6, 0.2, 0.3), yaw=0.25)
    view = View(robot, (box,))
    mapper = ObjectMapper(robot, params)
    for _ in range(5):
        mapper.integrate(view.observe())
    centre = np.array([0.5, 0.0])
    edf = mapper.local_edf(centre)
    truth = ground_truth_edf((box,), centre, params.edf_window_m, params.edf_voxel_m, params.theta_cutoff_m)
    assert edf.values.shape == truth.values.shape
    np.testing.assert_allclose(edf.origin, truth.origin)
    # everywhere in the window, inside the box too (its far side is fitted, not seen)
    assert np.max(np.abs(edf.values - truth.values)) <= params.edf_voxel_m
    view.close()
