"""The robot: UR10 on an omnidirectional base, q = [x, y, yaw, 6 arm joints]."""

from core.robot.collision_boxes import CollisionBox
from core.robot.collision_spheres import SPHERES, CollisionSphere
from core.robot.limits import JointLimits
from core.robot.model import RobotModel
from core.robot.symbolic_fk import SymbolicKinematics

__all__ = ["SPHERES", "CollisionBox", "CollisionSphere", "JointLimits", "RobotModel", "SymbolicKinematics"]
