import numpy as np
import pytest

from core.robot import SPHERES, ur10_assets
from core.robot.model import READY_Q
from core.robot.ur10_assets import RobotAssetsNotFoundError


def test_nine_joints_in_documented_order(robot):
    names = [robot.model.names[j] for j in range(1, robot.model.njoints)]
    assert names == ["base_x", "base_y", "base_yaw", "shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                     "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]


def test_limits_follow_method(robot):
    lim = robot.limits
    np.testing.assert_allclose(lim.v_max[:3], [1.0, 1.0, 0.75])
    assert lim.v_max[3:].min() >= 2.16 and lim.v_max[3:].max() <= 3.2
    assert np.all(np.isinf(lim.q_min[:3])) and np.all(np.isfinite(lim.q_min[3:]))
    assert np.all(lim.a_max > 0)
    clipped = lim.clip_velocity(np.array([5.0, -5.0, np.nan, 0, 0, 0, 0, 0, 10.0]))
    r = np.sqrt(0.5)  # the base's speed over the floor is 1 m/s along the diagonal too, not √2
    np.testing.assert_allclose(clipped, [r, -r, 0.0, 0, 0, 0, 0, 0, 3.2])


def test_the_base_speed_over_the_floor_is_clipped_to_its_limit_in_every_direction(robot):
    lim = robot.limits
    assert lim.planar_speed == 1.0
    theta = np.linspace(0.0, 2 * np.pi, 73)
    v = np.zeros((len(theta), 9))
    v[:, 0], v[:, 1], v[:, 2] = 3.0 * np.cos(theta), 3.0 * np.sin(theta), 0.5
    clipped = lim.clip_velocity(v)
    np.testing.assert_allclose(np.hypot(clipped[:, 0], clipped[:, 1]), 1.0)  # at the limit, never over it
    np.testing.assert_allclose(np.arctan2(clipped[:, 1], clipped[:, 0]), np.arctan2(v[:, 1], v[:, 0]), atol=1e-12)
    np.testing.assert_allclose(clipped[:, 2], 0.5)  # the yaw rate is its own limit
    slow = v.copy()
    slow[:, :2] *= 0.6 / 3.0
    np.testing.assert_allclose(lim.clip_velocity(slow), slow)  # under the limit: untouched
    assert not lim.within(np.zeros(9), np.r_[0.8, 0.8, np.zeros(7)])  # each axis within, the norm 1.13 not


def test_collision_geometry_table(robot):
    """The authors' arm spheres (docs/method.md, "Settings": upper arm 4 × 0.15, forearm 3 × 0.15, wrists
    0.15–0.2, tool 0.15), the mount and shoulder, and the base as its two boxes (the MuJoCo body and rack:
    `core/sim/collision_cover.py`)."""
    radii = {s.name: s.radius_m for s in SPHERES}
    assert [s.radius_m for s in SPHERES if s.name.startswith("upper_arm")] == [0.15] * 4
    assert [s.radius_m for s in SPHERES if s.name.startswith("forearm")] == [0.15] * 3
    assert all(0.15 <= r <= 0.2 for n, r in radii.items() if n.startswith("wrist"))
    assert radii["tool"] == 0.15
    centres = robot.sphere_centres(READY_Q)
    assert centres.shape == (13, 3) and robot.sphere_radii.shape == (13,)
    body, rack = robot.boxes
    np.testing.assert_allclose(body.hi - body.lo, [0.96, 0.79, 0.24])
    np.testing.assert_allclose(body.lo[2], 0.08)
    np.testing.assert_allclose(rack.hi - rack.lo, [0.4, 0.5, 0.6])
    np.testing.assert_allclose(rack.lo[2], body.hi[2])  # the rack stands on the top plate


def test_base_moves_whole_robot(robot):
    q = READY_Q.copy()
    moved = q.copy()
    moved[:3] = [1.0, -2.0, np.pi / 2]
    p0, p1 = robot.ee_pose(q)[:3, 3], robot.ee_pose(moved)[:3, 3]
    expected = np.array([1.0 - p0[1], -2.0 + p0[0], p0[2]])  # rotate by 90° then translate
    np.testing.assert_allclose(p1, expected, atol=1e-12)


def test_arm_mounted_like_a_ridgeback(robot):
    base_link = robot.frame_pose(np.zeros(9), "base_link")
    assert 0.5 < base_link[2, 3] < 0.8  # on top of the base, above the Ridgeback's 0.32 m body


def test_bad_configuration_rejected(robot):
    with pytest.raises(ValueError, match="9 finite"):
        robot.ee_pose(np.full(9, np.nan))
    with pytest.raises(ValueError):
        robot.ee_pose(np.zeros(7))


def test_missing_assets_give_clear_error(monkeypatch, tmp_path):
    ur10_assets.ur_description_dir.cache_clear()
    monkeypatch.setattr(ur10_assets, "_candidate_roots", lambda: [tmp_path])
    with pytest.raises(RobotAssetsNotFoundError, match="example-robot-data"):
        ur10_assets.ur10_urdf()
    ur10_assets.ur_description_dir.cache_clear()
