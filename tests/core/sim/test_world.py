"""The MuJoCo world: velocity tracking, scene edits while running, contacts, distances."""

import mujoco
import numpy as np
import pytest

from core.robot.model import READY_Q
from core.scene import Box, Scene
from core.sim.world import SceneEditError, SimWorld


def run(world: SimWorld, qdot, seconds: float) -> None:
    world.set_velocity_command(np.asarray(qdot, float))
    world.step(int(round(seconds / world.params.timestep_s)))


def test_model_kinematics_equal_pinocchio(world, robot):
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = robot.random_q(rng)
        world.set_robot(q)
        site = world.model.site("ee").id
        np.testing.assert_allclose(world.data.site_xpos[site], robot.ee_pose(q)[:3, 3], atol=1e-9)
        np.testing.assert_allclose(world.data.site_xmat[site].reshape(3, 3), robot.ee_pose(q)[:3, :3], atol=1e-9)
        for j, s in enumerate(robot.spheres):
            np.testing.assert_allclose(world.data.site_xpos[world.model.site(f"sphere_{s.name}").id],
                                       robot.sphere_centres(q)[j], atol=1e-9)


def test_velocity_commands_tracked_within_limits(world, robot):
    world.set_robot(READY_Q)
    qdot = 0.8 * robot.limits.v_max * np.array([1, -1, 1, 1, -1, 1, -1, 1, -1])
    qdot[:2] *= 0.75  # the base at 0.85 m/s over the floor, within its planar limit
    run(world, qdot, 0.3)
    v = world.state().v
    np.testing.assert_allclose(v, qdot, rtol=0.03, atol=0.01)
    assert np.all(np.abs(v) <= robot.limits.v_max * 1.01)


def test_commands_beyond_limits_are_clipped(world, robot):
    world.set_robot(READY_Q)
    run(world, 10.0 * np.ones(9), 0.3)
    v = world.state().v
    assert np.all(np.abs(v) <= robot.limits.v_max * 1.01)
    assert np.hypot(v[0], v[1]) <= robot.limits.planar_speed * 1.01  # 1 m/s over the floor, not √2 m/s
    np.testing.assert_allclose(v, robot.limits.clip_velocity(10.0 * np.ones(9)), rtol=0.03)


def test_nan_command_stops(world):
    world.set_robot(READY_Q)
    run(world, np.full(9, 0.3), 0.3)
    run(world, np.full(9, np.nan), 0.3)
    assert np.all(np.isfinite(world.state().q))
    np.testing.assert_allclose(world.state().v, 0.0, atol=0.02)


def _assert_state_kept(world, action):
    before = world.state()
    action()
    after = world.state()
    np.testing.assert_array_equal(before.q, after.q)
    np.testing.assert_array_equal(before.v, after.v)
    assert before.t == after.t


def test_box_add_move_remove_mid_run_keep_robot_state(world):
    world.set_robot(READY_Q)
    run(world, [0.3, 0.1, 0.2, 0.2, 0, 0, 0, 0, 0], 0.2)
    _assert_state_kept(world, lambda: world.add_box(Box("b1", (3.0, 1.0, 0.3))))
    _assert_state_kept(world, lambda: world.move_box("b1", (3.5, -1.0, 0.3), yaw=0.4))
    geom = world.model.geom("box_geom_0").id
    np.testing.assert_allclose(world.data.geom_xpos[geom], [3.5, -1.0, 0.3])
    _assert_state_kept(world, lambda: world.remove_box("b1"))
    assert world.boxes() == ()
    run(world, [0.3, 0.1, 0.2, 0.2, 0, 0, 0, 0, 0], 0.1)  # still runs


def test_pool_growth_recompiles_and_keeps_state(robot):
    from core.params import SimParams

    world = SimWorld(robot, SimParams(box_pool=2))
    world.set_robot(READY_Q)
    run(world, [0.3, 0, 0.2, 0, 0, 0, 0, 0, 0], 0.2)
    world.add_box(Box("a", (3, 0, 0.3)))
    world.add_box(Box("b", (3, 2, 0.3), (0.4, 0.5, 0.6)))
    version = world.model_version

    def add_third():
        world.add_box(Box("c", (3, -2, 0.3)))

    before = world.state()
    add_third()
    after = world.state()
    np.testing.assert_allclose(after.q, before.q, atol=1e-12)
    np.testing.assert_allclose(after.v, before.v, atol=1e-12)
    assert world.model_version == version + 1
    geom_b = world.model.geom("box_geom_1").id
    np.testing.assert_allclose(world.model.geom_size[geom_b], [0.2, 0.25, 0.3])
    np.testing.assert_allclose(world.data.geom_xpos[geom_b], [3, 2, 0.3])
    v_before = world.state().v
    run(world, [0.3, 0, 0.2, 0, 0, 0, 0, 0, 0], 0.05)
    np.testing.assert_allclose(world.state().v[:3], v_before[:3], atol=0.02)  # gains survived


def test_box_inside_robot_rejected_and_nothing_lost(world):
    world.add_box(Box("keep", (3.0, 0.0, 0.3)))
    world.set_robot(READY_Q)
    with pytest.raises(SceneEditError, match="overlap the robot"):
        world.add_box(Box("inside", (0.0, 0.0, 0.3)))
    assert [b.id for b in world.boxes()] == ["keep"]
    with pytest.raises(SceneEditError, match="overlap the robot"):
        world.move_box("keep", (0.1, 0.0, 0.3))
    assert world.box("keep").position == (3.0, 0.0, 0.3)


def test_bad_edits_are_named(world):
    with pytest.raises(SceneEditError, match="finite"):
        world.add_box(Box("nan", (np.nan, 0.0, 0.3)))
    with pytest.raises(SceneEditError, match="positive"):
        world.add_box(Box("flat", (3.0, 0.0, 0.3), (0.6, 0.0, 0.6)))
    with pytest.raises(SceneEditError, match="no box"):
        world.move_box("ghost", (1.0, 1.0, 0.3))
    world.add_box(Box("a", (3.0, 0.0, 0.3)))
    with pytest.raises(SceneEditError, match="exists"):
        world.add_box(Box("a", (4.0, 0.0, 0.3)))


def test_distance_and_collision_events(world):
    world.load_scene(Scene((Box("wall", (1.6, 0.0, 0.3), (0.2, 2.0, 0.6)),), robot_start=(0.0, 0.0, 0.0)))
    d0, box = world.robot_box_distance()
    assert box == "wall" and 0.0 < d0 < 1.6
    assert world.collisions == []
    run(world, [0.5, 0, 0, 0, 0, 0, 0, 0, 0], 3.0)
    assert world.collisions and world.collisions[0].box_id == "wall"
    assert world.robot_box_distance()[0] < 0.01
    assert world.state().q[0] < 1.6  # the box stopped the robot


def test_distance_from_some_robot_geoms_to_some_boxes(world):
    """The query restricted to named robot geoms and box ids equals MuJoCo's distance over those pairs."""
    world.load_scene(Scene((Box("near", (1.3, 0.0, 0.3)), Box("far", (-2.5, 1.0, 0.3))),
                           robot_start=(0.0, 0.0, 0.0)))
    geoms = ("base_body", "geom_wrist_3_link")
    dist, box = world.robot_box_distance(geoms, {"far"}, margin_m=5.0)
    assert box == "far"
    assert dist == pytest.approx(_brute_force(world, geoms, "far"), abs=1e-9)
    assert world.robot_box_distance(geoms, {"near"}, 5.0)[0] < dist
    assert world.robot_box_distance(geoms, {"far"}, margin_m=0.5) == (0.5, None)  # beyond the margin


def _brute_force(world, geoms, box_id: str) -> float:
    m, d = world.model, world.data
    g = next(k for k in range(m.ngeom) if world.box_id_of_geom(k) == box_id)
    return min(mujoco.mj_geomDistance(m, d, m.geom(name).id, g, 10.0, None) for name in geoms)


def test_walls_are_obstacles(robot):
    from core.params import SimParams
    from core.sim.ground_truth import scene_signed_distance

    world = SimWorld(robot, SimParams(walls=True, room_half_size_m=4.0))
    assert {b.id for b in world.obstacles()} == {"wall_east", "wall_west", "wall_north", "wall_south"}
    d = scene_signed_distance(np.array([[3.0, 0.0, 0.5]]), world.obstacles())
    assert d[0] == pytest.approx(0.95)
    world.set_robot(np.r_[3.0, 0.0, 0.0, READY_Q[3:]])
    run(world, [1.0, 0, 0, 0, 0, 0, 0, 0, 0], 2.0)
    assert any(c.box_id == "wall" for c in world.collisions)


def test_resized_boxes_collide_off_centre(world):
    """A big box whose centre is far from the robot but whose face overlaps it must make contact
    (the mid-phase bounding volume follows the resize)."""
    world.set_robot(READY_Q)
    world.add_box(Box("long", (2.3, 0.0, 0.3), (2.0, 0.4, 0.6)), check_robot=False)
    run(world, [0.4, 0, 0, 0, 0, 0, 0, 0, 0], 3.0)
    assert world.collisions and world.collisions[0].box_id == "long"
    assert world.robot_box_distance()[0] > -0.02  # stopped at the face, not inside


def test_a_scene_with_a_box_inside_the_robot_is_refused_and_nothing_lost(world):
    """Loading a scene checks its boxes against the robot at the scene's start, as adding a box does; the
    world keeps its boxes and robot (a dry run, `check_scene`, changes nothing either way)."""
    world.load_scene(Scene((Box("keep", (3.0, 0.0, 0.3)),), name="before"))
    q = world.state().q.copy()
    placements = world.placements
    bad = Scene((Box("far", (4.0, 2.0, 0.3)), Box("inside", (0.1, 0.0, 0.3))), robot_start=(0.0, 0.0, 0.0),
                name="bad")
    for load in (world.load_scene, world.check_scene):
        with pytest.raises(SceneEditError, match="scene 'bad' refused: box 'inside' would overlap the robot by"):
            load(bad)
        assert [b.id for b in world.boxes()] == ["keep"] and world.scene_name == "before"
        np.testing.assert_array_equal(world.state().q, q)
        assert world.placements == placements
    world.check_scene(Scene((Box("ok", (2.0, 0.0, 0.3)),)))
    assert [b.id for b in world.boxes()] == ["keep"]
