"""Does the controller's collision geometry cover the robot that collides? Samples the surface of every
robot collision geom of the MuJoCo model (boxes face by face; meshes as MuJoCo collides them, by their
convex hull) and measures how far each sample lies outside the union of the controller's spheres and
base boxes (`RobotModel.spheres`, `RobotModel.boxes`). Zero everywhere means covered.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial import ConvexHull

from core.robot.model import RobotModel
from core.sim.world import SimWorld
from core.sim.world_spec import ROBOT_CONTYPE


def _box_surface(half: np.ndarray, spacing: float) -> np.ndarray:
    """Points on the six faces of a box of half sides `half`, at most `spacing` apart."""
    faces = []
    for axis in range(3):
        u, w = [i for i in range(3) if i != axis]
        a, b = np.meshgrid(*(np.linspace(-half[i], half[i], max(2, int(np.ceil(2 * half[i] / spacing)) + 1))
                             for i in (u, w)))
        for sign in (-1.0, 1.0):
            p = np.zeros((a.size, 3))
            p[:, u], p[:, w], p[:, axis] = a.ravel(), b.ravel(), sign * half[axis]
            faces.append(p)
    return np.vstack(faces)


def _hull_surface(vertices: np.ndarray, spacing: float, rng: np.random.Generator) -> np.ndarray:
    """The hull's vertices and random points on its faces, about one per spacing² of area (at least 3)."""
    hull = ConvexHull(vertices)
    points = [vertices[hull.vertices]]
    for a, b, c in vertices[hull.simplices]:
        n = max(3, int(0.5 * np.linalg.norm(np.cross(b - a, c - a)) / spacing**2))
        r = rng.random((n, 2))
        r[r.sum(axis=1) > 1] = 1 - r[r.sum(axis=1) > 1]
        points.append(a + r[:, :1] * (b - a) + r[:, 1:] * (c - a))
    return np.vstack(points)


def _robot_geoms(m: mujoco.MjModel) -> list[int]:
    return [g for g in range(m.ngeom) if m.geom_contype[g] == ROBOT_CONTYPE]


def robot_surface_samples(world: SimWorld, spacing_m: float = 0.01, seed: int = 0) -> dict[str, np.ndarray]:
    """Surface samples of every robot collision geom, in its geom frame (name → (n, 3))."""
    m = world.model
    rng = np.random.default_rng(seed)
    out = {}
    for g in _robot_geoms(m):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            out[name] = _box_surface(m.geom_size[g], spacing_m)
        elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            mesh = m.geom_dataid[g]
            start = m.mesh_vertadr[mesh]
            out[name] = _hull_surface(m.mesh_vert[start:start + m.mesh_vertnum[mesh]].astype(float), spacing_m, rng)
        else:
            raise ValueError(f"robot geom {name!r} has a type this check does not sample ({m.geom_type[g]})")
    return out


def outside_distance(robot: RobotModel, q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """How far (m) each world point lies outside the union of the controller's spheres and base boxes at q
    (0 inside, to 1e-12 m; the distance to the nearest of them otherwise)."""
    gap = np.min(np.linalg.norm(points[:, None] - robot.sphere_centres(q)[None], axis=2) - robot.sphere_radii, axis=1)
    c, s = np.cos(q[2]), np.sin(q[2])
    d = points - np.array([q[0], q[1], 0.0])
    local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])
    for box in robot.boxes:
        out = np.maximum(np.maximum(box.lo - local, local - box.hi), 0.0)
        gap = np.minimum(gap, np.linalg.norm(out, axis=1))
    return np.where(gap > 1e-12, gap, 0.0)  # the box test's round-off (the frame turns with the yaw)


def cover_gaps(world: SimWorld, robot: RobotModel, configurations: list[np.ndarray],
               spacing_m: float = 0.01) -> dict[str, float]:
    """Per robot geom, the largest distance of any of its surface samples outside the controller's geometry,
    over the configurations (the world's robot is moved to each)."""
    samples = robot_surface_samples(world, spacing_m)
    worst = dict.fromkeys(samples, 0.0)
    for q in configurations:
        world.set_robot(q)
        with world.lock:
            poses = {name: (world.data.geom(name).xpos.copy(), world.data.geom(name).xmat.reshape(3, 3).copy())
                     for name in samples}
        for name, local in samples.items():
            pos, R = poses[name]
            worst[name] = max(worst[name], float(outside_distance(robot, q, local @ R.T + pos).max()))
    return worst
