"""Conservative geometry from partial views, on rendered frames: what lies behind a seen face is solid to an
assumed depth until free space is seen there; a second side gives the real depth; a floating box keeps the
space under it free; a lower part hidden behind another box stays solid."""

from dataclasses import replace

import numpy as np
import pytest

from core.mapping import ObjectMapper
from core.mapping.box_fit import BoxFit
from core.mapping.completion import Completion
from core.params import SensorParams
from core.robot.model import READY_Q
from core.scene import Box
from tests.core.mapping.rendered_views import View


@pytest.fixture(params=["noise", "camera model"])
def sensor(request) -> SensorParams:
    """Depth noise 0.005 z² alone, and the whole camera model (noise, dropouts, flying pixels)."""
    return replace(SensorParams.ideal(), depth_noise_m=0.005) if request.param == "noise" else SensorParams()


def _inside(box: Box, inset: float = 0.05, step: float = 0.05) -> np.ndarray:
    """Grid points inside a (yaw 0) box, `inset` from its faces."""
    half = np.array(box.size) / 2 - inset
    axes = [np.arange(-h, h + 1e-9, step) for h in half]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) + np.array(box.position)


def _at(x: float, y: float, yaw: float) -> np.ndarray:
    q = READY_Q.copy()
    q[:3] = x, y, yaw
    return q


def _observe(view: View, mapper: ObjectMapper, frames: int) -> None:
    for _ in range(frames):
        mapper.integrate(view.observe())


def test_stacked_boxes_seen_from_the_front_are_solid_behind_it_and_get_their_depth_from_the_side(robot, params, sensor):
    # two boxes 0.4 deep stacked 1.2 m high: from the front a face 0.6 wide, seen up to the image's upper edge
    low, top = Box("low", (2.0, 0.0, 0.3), (0.4, 0.6, 0.6)), Box("top", (2.0, 0.0, 0.9), (0.4, 0.6, 0.6))
    view = View(robot, (low, top), sensor=sensor)
    mapper = ObjectMapper(robot, params)
    _observe(view, mapper, 10)
    (obj,) = mapper.objects.values()
    assert obj.extent[0] < 0.1  # a face: the fitted box alone is a slab
    edf = mapper.local_edf(np.array([1.5, 0.0]))
    for box in (low, top):
        assert np.all(edf.distance(_inside(box)) <= 0.0), box.id  # no free space inside either box
        assert edf.distance(np.array([box.position]))[0] <= -0.1
    behind = np.array([[2.35, 0.0, 0.3], [2.35, 0.0, 0.9]])  # 0.15 m behind the real back face
    assert np.all(edf.distance(behind) <= 0.0)  # the assumed depth (0.6 m) covers it, not yet seen free
    view.world.set_robot(_at(2.0, -1.7, np.pi / 2))  # the side: rays past the back edge see free space
    _observe(view, mapper, 12)
    obj = next(iter(mapper.objects.values()))
    assert abs(obj.solid.extent[0] - 0.4) < 0.1 and abs(obj.extent[0] - 0.4) < 0.1
    edf = mapper.local_edf(np.array([1.5, 0.0]))
    for box in (low, top):
        assert np.all(edf.distance(_inside(box)) <= 0.0), box.id
    assert np.all(edf.distance(behind) > 0.0)  # the real depth: free behind the back face again
    view.close()


def test_the_papers_surface_edf_reads_free_space_inside_a_box_seen_from_the_front(robot, params):
    # the option beside completion (9a: distance to the observed surface voxels): the face is there, the inside
    # of the box behind it reads free
    box = Box("a", (2.0, 0.0, 0.3))
    view = View(robot, (box,), cameras=("hand",))
    completed, surface = ObjectMapper(robot, params), ObjectMapper(robot, replace(params, edf_geometry="surface"))
    for _ in range(6):
        obs = view.observe()
        completed.integrate(obs)
        surface.integrate(obs)
    behind_face = np.array([[1.8, 0.0, 0.3], [2.0, 0.0, 0.3], [2.2, 0.0, 0.3]])
    assert np.all(completed.local_edf(np.array([1.5, 0.0])).distance(behind_face) < 0.0)
    d = surface.local_edf(np.array([1.5, 0.0])).distance(behind_face)
    assert d[0] < 0.15 and np.all(d[1:] > 0.1)  # inside the box: free by up to the distance to its top face
    with pytest.raises(ValueError, match="edf_geometry"):
        ObjectMapper(robot, replace(params, edf_geometry="voxels"))
    view.close()


def test_a_box_at_hand_height_stays_floating(robot, params, sensor):
    shelf = Box("shelf", (2.0, 0.0, 1.0), (0.6, 0.6, 0.3))  # underside at 0.85 m
    view = View(robot, (shelf,), sensor=sensor)
    mapper = ObjectMapper(robot, params)
    _observe(view, mapper, 12)
    assert len(mapper.objects) == 1
    edf = mapper.local_edf(np.array([1.5, 0.0]))
    under = np.array([[1.8, 0.0, 0.3], [2.0, 0.0, 0.5], [2.2, 0.1, 0.6], [1.9, -0.2, 0.2]])
    truth = 0.85 - under[:, 2]
    assert np.all(edf.distance(under) >= truth - 0.1)  # free under it to within a voxel (was a column: < 0)
    assert np.all(edf.distance(_inside(shelf)) <= 0.0)  # and the box itself is solid
    view.close()


def test_a_lower_part_hidden_behind_another_box_stays_solid(robot, params, sensor):
    front, rear = Box("front", (1.5, 0.0, 0.2), (0.4, 1.0, 0.4)), Box("rear", (2.2, 0.0, 0.4), (0.4, 0.6, 0.8))
    view = View(robot, (front, rear), sensor=sensor)
    mapper = ObjectMapper(robot, params)
    _observe(view, mapper, 12)
    edf = mapper.local_edf(np.array([1.5, 0.0]))
    hidden = _inside(Box("hidden", (2.2, 0.0, 0.2), (0.4, 0.6, 0.4)))  # the rear box's lower half
    assert np.all(edf.distance(hidden) <= 0.0)
    view.close()


def test_completion_reaches_away_from_the_cameras_and_stops_at_free_space():
    face = BoxFit(centre=np.array([0.0, 0.0, 0.3]), yaw=0.0, extent=np.array([0.02, 0.6, 0.6]))  # seen from -x
    c = Completion(step_m=0.1, assumed_depth_m=0.6, confirm=2)
    c.saw_from(np.array([-2.0, 0.0, 1.0]))  # a camera above the top, in front of the face
    lo, hi = c.reach(face, floor_z=0.0)
    assert hi[0] == pytest.approx(0.01 + 0.58) and lo[0] == pytest.approx(-0.01)  # away from the camera
    assert lo[2] == pytest.approx(-0.3) and hi[2] == pytest.approx(0.3)  # already on the floor, seen from above
    samples = c.samples(face, 0.0)
    assert len(samples) and np.all(samples[:, 0] > 0.05)
    free = samples[samples[:, 0] >= 0.35]
    for _ in range(2):  # seen through twice: free; the reach ends half a step before the nearest free sample
        c.mark(free, np.ones(len(free), bool), np.zeros(len(free), bool))
    assert c.reach(face, 0.0)[1][0] == pytest.approx(free[:, 0].min() - 0.05)
    c.saw_from(np.array([2.0, 0.0, 1.0]))  # seen from the other side too: no reach at all
    assert c.reach(face, 0.0)[1][0] == pytest.approx(0.01)
    low = Completion(step_m=0.1, assumed_depth_m=0.6, confirm=2)
    low.saw_from(np.array([-2.0, 0.0, 0.0]))  # only from below its top (1.2 m): it may be taller
    high = BoxFit(centre=np.array([0.0, 0.0, 1.0]), yaw=0.0, extent=np.array([0.6, 0.6, 0.4]))
    lo, hi = low.reach(high, floor_z=0.0)
    assert lo[2] == pytest.approx(-1.0) and hi[2] == pytest.approx(0.2 + 0.6)
