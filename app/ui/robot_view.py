"""Draw the robot in viser: UR10 visual meshes and a Ridgeback-like base, posed from joint states."""

from __future__ import annotations

import logging
from functools import cache

import numpy as np
import trimesh
import trimesh.visual
import viser
import viser.transforms as vtf

from core.robot.model import RobotModel
from core.robot.ur10_assets import ARM_LINKS, ur10_mesh
from core.types import vec3

log = logging.getLogger(__name__)


@cache
def _link_mesh(link: str, kind: str = "collision") -> trimesh.Trimesh:
    """A UR10 link's mesh: 'collision' (5.8k triangles for the arm, what software WebGL draws smoothly) or
    'visual' (116k triangles)."""
    loaded = trimesh.load(ur10_mesh(link, kind))
    mesh = loaded.to_geometry() if isinstance(loaded, trimesh.Scene) else loaded
    if not isinstance(mesh, trimesh.Trimesh):
        raise TypeError(f"{ur10_mesh(link, kind)} holds no triangle mesh")
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=(150, 160, 175, 255))
    return mesh


def wxyz(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    return vtf.SO3.from_matrix(R).wxyz


class RobotView:
    """Scene nodes of the robot under `/robot`; `update(q)` moves them."""

    def __init__(self, server: viser.ViserServer, robot: RobotModel, name: str = "/robot",
                 meshes: str = "collision") -> None:
        self.robot = robot
        self.frames: dict[str, viser.FrameHandle] = {}
        for link in robot.link_names:
            frame = server.scene.add_frame(f"{name}/{link}", show_axes=False)
            self.frames[link] = frame
            if link == "mobile_base":
                for box, colour in zip(robot.boxes, ((45, 45, 50), (60, 60, 66)), strict=True):
                    server.scene.add_box(f"{name}/{link}/{box.name}", color=colour,
                                         dimensions=vec3(2 * h for h in box.half_m), position=box.centre_m)
            elif link in ARM_LINKS:
                server.scene.add_mesh_trimesh(f"{name}/{link}/mesh", _link_mesh(link, meshes))

    def update(self, q: np.ndarray) -> None:
        """Pose every link from the joint state q[9]."""
        for link, T in self.robot.link_poses(q).items():
            frame = self.frames[link]
            frame.position = T[:3, 3]
            frame.wxyz = wxyz(T[:3, :3])
