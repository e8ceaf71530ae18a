"""Unknown space (docs/method.md, "Unknown space is not free"): floor rays that return no depth, on real MuJoCo
frames with the sensor model (noise, 2 % dropouts, flying pixels), and the columns they make in the field."""

from dataclasses import replace

import numpy as np

from core.mapping.self_filter import SelfFilter
from core.mapping.unknown_floor import UnknownFloor, unknown_columns
from core.params import SensorParams
from core.robot.model import RobotModel
from core.scene import Box
from core.types import LocalEDF, UnknownSpace
from tests.core.mapping.rendered_views import View

FACE_X = 1.7
"""The near face of the test box (centre x = 2.0, 0.6 m deep); the base camera sits at x = 0.5, 0.38 m up."""
CAMERA_X = 0.5


def _integrate(view: View, floor: UnknownFloor, frames: int) -> None:
    for _ in range(frames):
        for frame in view.observe().frames:
            floor.integrate(frame)


def _box(dark: bool) -> Box:
    return Box("b", (2.0, 0.0, 0.3), (0.6, 0.6, 0.6), dark=dark)


def test_a_dark_box_leaves_the_floor_behind_its_face_unknown(params):
    robot = RobotModel()
    view = View(robot, (_box(dark=True),), cameras=("base",), sensor=SensorParams())
    floor = UnknownFloor(params)
    _integrate(view, floor, 3)
    cells = floor.centres()
    assert len(cells) > 20, "the box's shadow on the floor was not marked unknown"
    half = params.unknown_cell_m
    assert cells[:, 0].min() < FACE_X + 2 * half, "the unknown space does not start at the box's face"
    assert cells[:, 0].min() > FACE_X - 2 * half, "floor seen before the face was marked unknown"
    cone = 0.3 * (cells[:, 0] - CAMERA_X) / (FACE_X - CAMERA_X) + 2 * half  # the box's shadow, seen from the camera
    assert np.all(np.abs(cells[:, 1]) <= cone)
    view.close()


def test_a_box_that_returns_depth_and_random_dropouts_leave_no_unknown_floor(params):
    robot = RobotModel()
    view = View(robot, (_box(dark=False),), cameras=("hand", "base"), sensor=SensorParams(), seed=3)
    floor = UnknownFloor(params)
    _integrate(view, floor, 20)
    assert len(floor.keys) == 0, f"{len(floor.keys)} cells unknown without a dark surface"
    view.close()


REACHING_DOWN = np.array([0.0, 0.0, 0.0, -2.505, -4.005, 2.545, 3.768, 1.96, -0.364])
"""The arm at the aisle laps' pick at stop A (20.7 s): the forearm passes a few centimetres in front of the base
camera, nearer than its near clip, so its pixels read 0."""


def test_rays_that_meet_the_robots_own_body_are_no_evidence(params):
    robot = RobotModel()
    view = View(robot, (), cameras=("base",), q=REACHING_DOWN, sensor=SensorParams())
    blind, aware = UnknownFloor(params), UnknownFloor(params)
    self_filter = SelfFilter(robot, params.self_filter_margin_m)
    for _ in range(3):
        obs = view.observe()
        for frame in obs.frames:
            blind.integrate(frame)
            aware.integrate(frame, self_filter.body(obs.q_at(frame.t)))
    assert len(blind.keys) > 10, "the arm did not hide the floor: this test needs a pose where it does"
    assert len(aware.keys) == 0, f"{len(aware.keys)} cells unknown behind the robot's own arm"
    view.close()


def test_random_dropouts_over_many_frames_of_open_floor_leave_no_unknown_floor(params):
    """The far cells get 5 rays a frame: 3 random dropouts among them happen every few frames somewhere in view,
    so a cell turns unknown only on evidence summed over rays and frames that dropouts do not give."""
    robot = RobotModel()
    view = View(robot, (), cameras=("base",), sensor=SensorParams(), seed=5)
    floor = UnknownFloor(params)
    ever = 0
    for _ in range(300):  # a cell unknown in any one frame slows the base then: count them all
        _integrate(view, floor, 1)
        ever += len(floor.keys)
    assert ever == 0, f"{ever} cell-frames unknown on open floor"
    view.close()


def test_floor_seen_again_is_free_again(params):
    """A dark box taken away: the floor behind where it stood returns depth again, and the cells clear."""
    robot = RobotModel()
    view = View(robot, (_box(dark=True),), cameras=("base",), sensor=SensorParams())
    floor = UnknownFloor(params)
    _integrate(view, floor, 2)
    assert len(floor.keys) > 0
    view.world.remove_box("b")
    _integrate(view, floor, 2)
    assert len(floor.keys) == 0
    view.close()


def test_unknown_columns_are_obstacles_of_the_signed_field():
    """Nine cells (0.3 m square at x = 1, 1 m tall) joined with a field holding another obstacle: the distance is
    the smaller of the two, negative inside the columns, measured to the columns' top above them."""
    voxel, cutoff = 0.1, 1.8
    shape = (41, 41, 15)
    origin = np.array([-2.0, -2.0, 0.0])
    nodes = origin + voxel * np.stack(np.meshgrid(*(np.arange(n) for n in shape), indexing="ij"), axis=-1)
    other = np.clip(np.linalg.norm(nodes - [-1.0, 0.0, 0.3], axis=-1) - 0.3, -cutoff, cutoff)  # a ball at x = −1
    space = UnknownSpace(centres=np.array([[1.0 + i * 0.1, j * 0.1] for i in (-1, 0, 1) for j in (-1, 0, 1)]),
                         cell_m=0.1, height_m=1.0)
    edf = unknown_columns(LocalEDF(origin, voxel, other, cutoff), space)
    assert edf.unknown is space
    probes = np.array([[0.35, 0.0, 0.5], [1.0, 0.0, 0.5], [1.0, 0.0, 1.3], [-1.0, 0.0, 0.3], [1.0, 1.15, 0.2]])
    truth = np.array([0.5, -0.15, 0.3, -0.3, 1.0])
    np.testing.assert_allclose(edf.distance(probes), truth, atol=voxel)
    assert edf.distance(probes[1]) < 0
    empty = unknown_columns(LocalEDF(origin, voxel, other, cutoff), replace(space, centres=np.zeros((0, 2))))
    np.testing.assert_array_equal(empty.values, other)


def test_unknown_space_distance_is_to_the_nearest_column():
    space = UnknownSpace(centres=np.array([[1.0, 0.0], [3.0, 0.0]]), cell_m=0.2, height_m=1.0)
    d, nearest = space.distance(np.array([[0.0, 0.0, 0.5], [2.0, 0.0, 1.5], [1.0, 0.05, 0.5]]))
    np.testing.assert_allclose(d, [0.9, np.hypot(0.9, 0.5), 0.0])
    np.testing.assert_allclose(nearest[0], [0.9, 0.0, 0.5])
