"""`SimWorld`: the MuJoCo model and data of robot and boxes, owned in one place, edited while it runs.

Scene edits while running (measured in `bench/sim_rate.py` and `tests/core/sim/test_world.py`):
- move a box: write its mocap pose and run `mj_forward` (tens of µs); no recompile;
- add a box: fill a parked slot (set geom size, bounding radius and pose); no recompile;
- remove a box: park its slot under the floor; no recompile;
- add beyond the pool: `MjSpec.recompile` with twice the slots; MuJoCo carries qpos, qvel, ctrl and time
  over, so the robot's state is kept; renderers notice through `model_version` and rebuild.
All public methods take the world's lock, so a UI thread may edit while the physics thread steps.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Collection, Iterable
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from core.errors import StudioError
from core.params import SimParams
from core.robot.model import RobotModel
from core.scene import Box, Scene
from core.sim.world_spec import PARKED_Z_M, add_box_slots, box_rgba, build_world_spec, wall_boxes
from core.types import RobotState

log = logging.getLogger(__name__)

VELOCITY_TIME_CONSTANT_S = 0.002
"""Velocity actuators are tuned per joint (kv = M_ii / tau) so each joint tracks within a few physics steps."""


class SceneEditError(StudioError, ValueError):
    """A scene edit that cannot be applied (unknown id, bad numbers, a box inside the robot)."""


@dataclass(frozen=True)
class CollisionEvent:
    """Contact between a robot geom and a box at sim time t (penetration depth in m, ≥ 0)."""

    t: float
    box_id: str
    robot_geom: str
    depth_m: float


def _finite(values, what: str) -> None:
    if not np.all(np.isfinite(np.asarray(values, dtype=float))):
        raise SceneEditError(f"{what} must be finite numbers, got {values!r}")


class SimWorld:
    """Robot and boxes in MuJoCo; the single owner of `model` and `data`."""

    def __init__(self, robot: RobotModel | None = None, params: SimParams | None = None,
                 scene: Scene | None = None) -> None:
        self.robot = robot or RobotModel()
        self.params = params or SimParams()
        self.lock = threading.RLock()
        self.model_version = 0
        self.placements = 0
        """Counts `set_robot` teleports: a robot's odometry restarts from the true pose after one."""
        self._slots = self.params.box_pool
        self.spec = build_world_spec(self.robot, self.params, self._slots)
        self.model = self.spec.compile()
        self.data = mujoco.MjData(self.model)
        self._boxes: dict[str, Box] = {}
        self._slot_of: dict[str, int] = {}
        self._free: list[int] = list(range(self._slots))
        self.collisions: list[CollisionEvent] = []
        self._index()
        self._tune_gains()
        self.scene_name = "empty"
        if scene is not None:
            self.load_scene(scene)

    # --- model bookkeeping ---------------------------------------------------------------------

    def _index(self) -> None:
        m = self.model
        self._qadr = np.array([m.jnt_qposadr[m.joint(n).id] for n in self.joint_names])
        self._vadr = np.array([m.jnt_dofadr[m.joint(n).id] for n in self.joint_names])
        self._robot_geoms = np.array([g for g in range(m.ngeom) if m.geom_contype[g] == 1])
        self._slot_body = np.array([m.body(f"box_slot_{k}").id for k in range(self._slots)])
        self._slot_geom = np.array([m.geom(f"box_geom_{k}").id for k in range(self._slots)])
        self._slot_mocap = m.body_mocapid[self._slot_body]
        self._geom_slot = {int(g): k for k, g in enumerate(self._slot_geom)}

    @property
    def joint_names(self) -> list[str]:
        return ["base_x", "base_y", "base_yaw", *[self.robot.model.names[j] for j in range(4, 10)]]

    def _tune_gains(self) -> None:
        """Per-joint velocity gains from the joint-space inertia at the ready pose."""
        from core.robot.model import READY_Q

        self.data.qpos[self._qadr] = READY_Q
        mujoco.mj_forward(self.model, self.data)
        M = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, M)
        kv = np.diag(M)[self._vadr] / VELOCITY_TIME_CONSTANT_S
        self.model.actuator_gainprm[:, 0] = kv
        self.model.actuator_biasprm[:, 2] = -kv
        self.data.qpos[:] = 0.0
        mujoco.mj_forward(self.model, self.data)

    # --- robot ---------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        return float(self.data.time)

    def state(self) -> RobotState:
        """Joint positions and velocities now."""
        with self.lock:
            return RobotState(self.time, self.data.qpos[self._qadr].copy(), self.data.qvel[self._vadr].copy())

    def set_robot(self, q: np.ndarray, v: np.ndarray | None = None) -> None:
        """Teleport the robot to q (and v, default zero); commands reset to zero."""
        q = np.asarray(q, dtype=float)
        if q.shape != (9,):
            raise SceneEditError(f"q must have 9 entries, got shape {q.shape}")
        _finite(q, "q")
        with self.lock:
            self._place(q, v)
            self.placements += 1

    def _place(self, q: np.ndarray, v: np.ndarray | None) -> None:
        self.data.qpos[self._qadr] = q
        self.data.qvel[self._vadr] = 0.0 if v is None else v
        self.data.ctrl[:] = 0.0
        mujoco.mj_forward(self.model, self.data)

    def set_velocity_command(self, qdot: np.ndarray) -> None:
        """Velocity set-points for the actuators; NaN becomes 0, values are clipped to the limits."""
        qdot = self.robot.limits.clip_velocity(np.asarray(qdot, dtype=float))
        with self.lock:
            self.data.ctrl[:] = qdot

    def step(self, n: int = 1) -> None:
        """Advance physics by n steps of `timestep_s`, recording robot–box contacts."""
        with self.lock:
            for _ in range(n):
                mujoco.mj_step(self.model, self.data)
                if self.data.ncon:
                    self._record_contacts()

    def _record_contacts(self) -> None:
        d = self.data
        for i in range(d.ncon):
            c = d.contact[i]
            if c.dist >= 0.0:
                continue
            slot = self._geom_slot.get(int(c.geom1), self._geom_slot.get(int(c.geom2)))
            robot_geom = c.geom2 if int(c.geom1) in self._geom_slot else c.geom1
            box_id = self._box_in_slot(slot) if slot is not None else "wall"
            self.collisions.append(CollisionEvent(self.time, box_id or "?", self.model.geom(robot_geom).name,
                                                  float(-c.dist)))

    # --- boxes ---------------------------------------------------------------------------------

    def boxes(self) -> tuple[Box, ...]:
        """The boxes now in the world."""
        with self.lock:
            return tuple(self._boxes.values())

    def obstacles(self) -> tuple[Box, ...]:
        """Everything the robot can hit: the boxes and the optional walls (for ground-truth queries)."""
        return self.boxes() + wall_boxes(self.params)

    def box(self, box_id: str) -> Box:
        with self.lock:
            if box_id not in self._boxes:
                raise SceneEditError(f"no box {box_id!r}; boxes: {sorted(self._boxes)}")
            return self._boxes[box_id]

    def _box_in_slot(self, slot: int) -> str | None:
        return next((b for b, s in self._slot_of.items() if s == slot), None)

    def load_scene(self, scene: Scene, place_robot: bool = True) -> None:
        """Replace all boxes by the scene's; optionally put the robot at the scene's start.

        A scene with a box that overlaps the robot (where it starts) raises `SceneEditError`, as a box added
        while running does, and leaves the world as it was."""
        with self.lock:
            before = self._saved()
            try:
                self._replace_boxes(scene, place_robot)
            except SceneEditError:
                self._restore(before)
                raise
            if place_robot:
                self.placements += 1

    def check_scene(self, scene: Scene) -> None:
        """Raise `SceneEditError` if loading `scene` would put a box inside the robot at the scene's start;
        the world is left as it was either way (a dry run of `load_scene`)."""
        with self.lock:
            before = self._saved()
            try:
                self._replace_boxes(scene, place_robot=True)
            finally:
                self._restore(before)

    def _replace_boxes(self, scene: Scene, place_robot: bool) -> None:
        for box_id in list(self._boxes):
            self.remove_box(box_id)
        if place_robot:
            from core.robot.model import READY_Q

            q = READY_Q.copy()
            q[:3] = scene.robot_start
            self._place(q, None)
        for box in scene.boxes:
            try:
                self.add_box(box)
            except SceneEditError as err:
                raise SceneEditError(f"scene {scene.name!r} refused: {err}") from err
        self.scene_name = scene.name

    def _saved(self) -> tuple[tuple[Box, ...], np.ndarray, np.ndarray, np.ndarray, str]:
        d = self.data
        return tuple(self._boxes.values()), d.qpos.copy(), d.qvel.copy(), d.ctrl.copy(), self.scene_name

    def _restore(self, saved: tuple[tuple[Box, ...], np.ndarray, np.ndarray, np.ndarray, str]) -> None:
        boxes, qpos, qvel, ctrl, name = saved
        for box_id in list(self._boxes):
            self.remove_box(box_id)
        self.data.qpos[:], self.data.qvel[:], self.data.ctrl[:] = qpos, qvel, ctrl
        mujoco.mj_forward(self.model, self.data)
        for box in boxes:
            self.add_box(box, check_robot=False)
        self.scene_name = name

    def scene(self) -> Scene:
        """The current boxes as a `Scene` (robot start = the robot's current base pose)."""
        with self.lock:
            q = self.data.qpos[self._qadr]
            return Scene(tuple(self._boxes.values()), self.params.walls, (float(q[0]), float(q[1]), float(q[2])),
                         self.scene_name)

    def add_box(self, box: Box, check_robot: bool = True) -> None:
        """Add a box while running; raises `SceneEditError` on a duplicate id, bad numbers or overlap."""
        _finite([*box.position, *box.size, box.yaw], f"box {box.id!r} pose and size")
        if min(box.size) <= 0.0:
            raise SceneEditError(f"box {box.id!r}: sizes must be positive, got {box.size}")
        with self.lock:
            if box.id in self._boxes:
                raise SceneEditError(f"a box with id {box.id!r} exists already")
            if not self._free:
                self._grow()
            slot = self._free.pop(0)
            self._slot_of[box.id] = slot
            self._boxes[box.id] = box
            self._set_geom_half_size(self._slot_geom[slot], np.array(box.size) / 2)
            self.model.geom_rgba[self._slot_geom[slot]] = box_rgba(box)
            self._write_pose(slot, box)
            if check_robot:
                self._reject_if_inside_robot(box.id, undo=lambda: self.remove_box(box.id))

    def move_box(self, box_id: str, position: tuple[float, float, float], yaw: float | None = None,
                 check_robot: bool = True) -> Box:
        """Move a box while running (a mocap pose write); returns the moved box."""
        _finite([*position, 0.0 if yaw is None else yaw], f"pose of box {box_id!r}")
        with self.lock:
            old = self.box(box_id)
            new = replace(old, position=tuple(float(p) for p in position), yaw=old.yaw if yaw is None else float(yaw))
            self._boxes[box_id] = new
            self._write_pose(self._slot_of[box_id], new)
            if check_robot:
                self._reject_if_inside_robot(box_id, undo=lambda: self.move_box(box_id, old.position, old.yaw, False))
            return new

    def remove_box(self, box_id: str) -> Box:
        """Remove a box while running (its slot is parked under the floor)."""
        with self.lock:
            box = self.box(box_id)
            slot = self._slot_of.pop(box_id)
            del self._boxes[box_id]
            mid = self._slot_mocap[slot]
            self.data.mocap_pos[mid] = (0.0, 0.0, PARKED_Z_M)
            self.data.mocap_quat[mid] = (1.0, 0.0, 0.0, 0.0)
            self._free.append(slot)
            mujoco.mj_forward(self.model, self.data)
            return box

    def _set_geom_half_size(self, geom: int, half: np.ndarray) -> None:
        """Resize a box geom in place. Size, bounding radius, AABB and the body's bounding-volume node
        all feed collision detection: a stale BVH node (compiled for the parked 5 cm box) made MuJoCo's
        mid-phase skip real contacts with a resized box."""
        m = self.model
        m.geom_size[geom] = half
        m.geom_rbound[geom] = float(np.linalg.norm(half))
        m.geom_aabb[geom] = np.concatenate([np.zeros(3), half])
        body = m.geom_bodyid[geom]
        m.bvh_aabb[m.body_bvhadr[body]] = np.concatenate([np.zeros(3), half])

    def _write_pose(self, slot: int, box: Box) -> None:
        mid = self._slot_mocap[slot]
        self.data.mocap_pos[mid] = box.position
        self.data.mocap_quat[mid] = (math.cos(box.yaw / 2), 0.0, 0.0, math.sin(box.yaw / 2))
        mujoco.mj_forward(self.model, self.data)

    def _reject_if_inside_robot(self, box_id: str, undo) -> None:
        g = int(self._slot_geom[self._slot_of[box_id]])
        d = min(mujoco.mj_geomDistance(self.model, self.data, int(r), g, 0.05, None) for r in self._robot_geoms)
        if d < 0.0:
            undo()
            raise SceneEditError(f"box {box_id!r} would overlap the robot by {-d * 100:.1f} cm; place it elsewhere")

    def _grow(self) -> None:
        """Double the box pool by recompiling; the robot's state and the boxes are carried over."""
        new_slots = self._slots
        add_box_slots(self.spec, self._slots, new_slots)
        kv = self.model.actuator_gainprm[:, 0].copy()
        mocap_pos, mocap_quat = self.data.mocap_pos.copy(), self.data.mocap_quat.copy()
        sizes = self.model.geom_size[self._slot_geom].copy()
        rgba = self.model.geom_rgba[self._slot_geom].copy()
        self.model, self.data = self.spec.recompile(self.model, self.data)
        self.data.mocap_pos[: len(mocap_pos)] = mocap_pos
        self.data.mocap_quat[: len(mocap_quat)] = mocap_quat
        self.model.actuator_gainprm[:, 0] = kv
        self.model.actuator_biasprm[:, 2] = -kv
        n_old = len(self._slot_geom)
        self._free.extend(range(self._slots, self._slots + new_slots))
        self._slots += new_slots
        self._index()
        for slot in range(n_old):  # recompiling restores the spec's sizes and colours: put the live ones back
            self._set_geom_half_size(self._slot_geom[slot], sizes[slot])
            self.model.geom_rgba[self._slot_geom[slot]] = rgba[slot]
        mujoco.mj_forward(self.model, self.data)
        self.model_version += 1
        log.info("box pool grown to %d slots (recompiled)", self._slots)

    # --- ground-truth queries --------------------------------------------------------------------

    def robot_box_distance(self, robot_geoms: Iterable[str] | None = None, box_ids: Collection[str] | None = None,
                           margin_m: float | None = None) -> tuple[float, str | None]:
        """Smallest signed distance (m) between robot geometry and any box, and that box's id.

        Optionally only the named robot geoms and the boxes of `box_ids`. Distances beyond `margin_m`
        (default `distance_margin_m`) are reported as that margin (no narrow phase needed).
        """
        with self.lock:
            best, best_id = self.params.distance_margin_m if margin_m is None else margin_m, None
            m, d = self.model, self.data
            robot = self._robot_geoms if robot_geoms is None else [m.geom(name).id for name in robot_geoms]
            for box_id, slot in self._slot_of.items():
                if box_ids is not None and box_id not in box_ids:
                    continue
                g = int(self._slot_geom[slot])
                centre, rb = d.geom_xpos[g], m.geom_rbound[g]
                for r in robot:
                    bound = np.linalg.norm(d.geom_xpos[r] - centre) - rb - m.geom_rbound[r]
                    if bound >= best:
                        continue
                    dist = mujoco.mj_geomDistance(m, d, int(r), g, best, None)
                    if dist < best:
                        best, best_id = dist, box_id
            return float(best), best_id

    def dark_geoms(self) -> np.ndarray:
        """Geom ids of the boxes whose surface returns no depth (`Box.dark`)."""
        with self.lock:
            return np.array([self._slot_geom[s] for b, s in self._slot_of.items() if self._boxes[b].dark], dtype=int)

    def box_id_of_geom(self, geom: int) -> str | None:
        """Box id of a geom index (for ground-truth segmentation), None for non-box geoms."""
        slot = self._geom_slot.get(int(geom))
        return None if slot is None else self._box_in_slot(slot)
