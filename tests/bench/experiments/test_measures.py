"""What the experiments measure, on hand-made cases: phantoms, in-view tests, collision bookkeeping."""

import numpy as np

from bench.experiments.measures import box_in_view, collision_bodies, in_view, phantoms
from core.scene import Box
from core.sim.world import CollisionEvent
from core.types import DepthFrame


def _cloud(centre, half=0.3, n=200, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.asarray(centre) + rng.uniform(-half, half, (n, 3))


def test_phantom_counted_where_a_moved_box_still_is_in_the_map():
    old_a, old_b = Box("a", (1.0, 0.0, 0.3)), Box("b", (3.0, 0.0, 0.3))
    occupied = np.vstack([_cloud(old_a.position), np.zeros((0, 3))])  # map still holds a, forgot b
    count = phantoms(occupied, (old_a, old_b), present=())
    assert count.count == 1 and count.ids == ("a",) and count.points == 200


def test_points_of_a_box_standing_there_now_are_not_a_phantom():
    old = Box("a", (1.0, 0.0, 0.3))
    other_now_there = Box("c", (1.0, 0.0, 0.3))
    count = phantoms(_cloud(old.position), (old,), present=(other_now_there,))
    assert count.count == 0 and count.points == 0


def test_a_few_stray_points_are_not_a_phantom():
    old = Box("a", (1.0, 0.0, 0.3))
    assert phantoms(_cloud(old.position, n=2), (old,), present=()).count == 0
    assert phantoms(np.zeros((0, 3)), (old,), present=()).count == 0


def _frame() -> DepthFrame:
    K = np.array([[160.0, 0, 160], [0, 160.0, 120], [0, 0, 1]])
    T = np.eye(4)  # camera at the origin looking along +z
    return DepthFrame(t=0.0, camera="base", depth=np.zeros((240, 320), np.float32), K=K, T_world_camera=T)


def test_in_view_needs_the_image_the_front_and_the_range():
    f = _frame()
    assert in_view(f, np.array([0.0, 0.0, 2.0]))
    assert not in_view(f, np.array([0.0, 0.0, -2.0]))  # behind
    assert not in_view(f, np.array([0.0, 0.0, 3.5]))  # beyond 3 m
    assert not in_view(f, np.array([5.0, 0.0, 2.0]))  # outside the image
    assert box_in_view([f], Box("a", (1.0, 0.0, 1.5)))  # one corner inside suffices
    assert not box_in_view([f], Box("a", (0.0, 0.0, -2.0)))


def test_collisions_split_into_base_and_arm():
    events = [CollisionEvent(t=0.0, box_id="a", robot_geom="base_body", depth_m=0.01),
              CollisionEvent(t=0.002, box_id="a", robot_geom="geom_forearm_link", depth_m=0.02),
              CollisionEvent(t=0.004, box_id="b", robot_geom="base_rack", depth_m=0.0)]
    assert collision_bodies(events) == {"base": 2, "arm": 1}


def test_approach_speed_is_how_fast_the_clearance_shrinks_not_the_speed():
    from app.runtime.run_log import RunLog
    from bench.experiments.measures import approach_speeds
    from core.types import RobotState

    log = RunLog()
    distances = [0.9, 0.5, 0.45, 0.45, 0.5, 2.0]  # approaches, then drives past, then leaves
    for k, d in enumerate(distances):
        log.record(RobotState(0.1 * k, np.zeros(9), np.zeros(9)), None, d, 0, "running", 0, np.zeros(9), {})
    rates = approach_speeds(log, near_m=0.6)
    np.testing.assert_allclose(rates, [0.5, 0.0, -0.5, -15.0])
