"""The base's actual speed when a box is pushed against the robot (test only: the world's boxes are kinematic
mocap bodies, of infinite mass). The base is commanded at its limit; whatever the box does, the command is
clipped to the limit (`JointLimits.clip_velocity`), and the actual speed over the floor stays within 5 % of
it, unless the box itself moves faster than the limit: then it carries the robot at its own speed (measured:
1.5 m/s behind a box at 1.5 m/s), an excess no command can prevent."""

import numpy as np
import pytest

from core.robot.model import READY_Q
from core.scene import Box
from core.sim.world import SimWorld


def _pushed(world: SimWorld, command: np.ndarray, start: tuple[float, float, float],
            box_velocity: tuple[float, float, float], seconds: float = 1.5) -> tuple[np.ndarray, int]:
    """Planar speeds (m/s) of the base at every physics step while the box moves at `box_velocity`; contacts."""
    world.set_robot(READY_Q)
    world.add_box(Box("pusher", start, (0.6, 0.6, 0.6)))
    dt = world.model.opt.timestep
    position, speeds = np.array(start), []
    for _ in range(int(round(seconds / dt))):
        world.set_velocity_command(command)
        position = position + np.asarray(box_velocity) * dt
        world.move_box("pusher", tuple(position), check_robot=False)  # pushed into the robot: test only
        world.step(1)
        speeds.append(float(np.hypot(*world.state().v[:2])))
    return np.array(speeds), len(world.collisions)


def _at_limit(world: SimWorld, direction_deg: float | None) -> np.ndarray:
    """A command twice the limit (clipped to it) in a direction; None: at rest."""
    qdot = np.zeros(9)
    if direction_deg is not None:
        theta = np.radians(direction_deg)
        qdot[:2] = 2.0 * np.cos(theta), 2.0 * np.sin(theta)
    return qdot


@pytest.mark.parametrize(("case", "direction_deg", "start", "box_velocity"), [
    ("box pushed into its side while it drives", 0.0, (0.3, -0.715, 0.3), (0.95, 0.3, 0.0)),
    ("box pushed into its side, driving diagonally", 45.0, (0.3, -0.715, 0.3), (0.5, 0.85, 0.0)),
    ("box pushed across its way, driving diagonally", 45.0, (0.3, -0.715, 0.3), (0.0, 0.85, 0.0)),
    ("box pushed into its back at the limit, at rest", None, (-0.8, 0.0, 0.3), (1.0, 0.0, 0.0)),
])
def test_a_pushed_base_stays_within_five_percent_of_its_limit(world, case, direction_deg, start, box_velocity):
    assert np.hypot(*box_velocity[:2]) <= world.robot.limits.planar_speed  # the box itself within the limit
    speeds, contacts = _pushed(world, _at_limit(world, direction_deg), start, box_velocity)
    limit = world.robot.limits.planar_speed
    assert contacts > 0, f"{case}: the box never touched the robot"
    assert speeds.max() <= 1.05 * limit, f"{case}: {speeds.max():.3f} m/s"
    assert np.hypot(*world.data.ctrl[:2]) <= limit + 1e-9


def test_a_box_faster_than_the_limit_carries_the_robot_at_its_own_speed(world):
    speeds, contacts = _pushed(world, _at_limit(world, 0.0), (-0.8, 0.0, 0.3), (1.5, 0.0, 0.0))
    assert contacts > 0
    assert np.hypot(*world.data.ctrl[:2]) <= world.robot.limits.planar_speed + 1e-9  # commanded at the limit
    assert speeds.max() > 1.05 * world.robot.limits.planar_speed  # the excess is the box's ...
    assert speeds.max() <= 1.5 * 1.05 and abs(speeds[-1] - 1.5) <= 0.05  # ... it moves the robot at its speed
