"""Scenes: boxes with ids, poses and sizes; YAML files; the paper's random scenes and an aisle.

A `Scene` is plain data; the world (`SimWorld`) turns it into MuJoCo bodies. Boxes stand on the floor
or on each other (two layers); the pose is the box centre and a yaw about z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import cast

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator
from scipy import ndimage

from core.atomic_file import write_text_atomic
from core.errors import StudioError
from core.yaml_validation import dump_yaml_model, load_yaml_file, load_yaml_model

PAPER_BOX_M = 0.6
"""Edge of the paper's boxes (m)."""



class SceneGenerationError(StudioError, RuntimeError):
    """No passable random scene was found within the tries given (try another seed or fewer boxes)."""


@dataclass(frozen=True)
class Box:
    """A rigid box: centre `position` (m), full `size` (m), `yaw` (rad) about the world z axis; a `dark` box's
    surface returns no depth (black, shiny or transparent: depth cameras see nothing there)."""

    id: str
    position: tuple[float, float, float]
    size: tuple[float, float, float] = (PAPER_BOX_M, PAPER_BOX_M, PAPER_BOX_M)
    yaw: float = 0.0
    dark: bool = False

    def pose(self) -> np.ndarray:
        """4×4 world pose of the box centre."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        T[:3, 3] = self.position
        return T

    def footprint_radius(self) -> float:
        """Half diagonal of the box in the floor plane (m)."""
        return 0.5 * math.hypot(self.size[0], self.size[1])


@dataclass(frozen=True)
class Scene:
    """Boxes, optional walls, and where the robot starts (x, y, yaw)."""

    boxes: tuple[Box, ...] = ()
    walls: bool = False
    robot_start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = "scene"
    goal: tuple[float, float] | None = None
    metadata: dict[str, float] = field(default_factory=dict)

    def box(self, box_id: str) -> Box:
        for b in self.boxes:
            if b.id == box_id:
                return b
        raise KeyError(f"no box {box_id!r} in scene {self.name!r}")

    def with_box(self, box: Box) -> Scene:
        """A copy with `box` added or replacing the box of the same id."""
        return replace(self, boxes=tuple(b for b in self.boxes if b.id != box.id) + (box,))


# --- files --------------------------------------------------------------------------------------

_Vec3 = tuple[float, float, float]


class BoxModel(BaseModel):
    """A box in a scene file."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    id: str = Field(min_length=1)
    position: _Vec3
    size: _Vec3 = (PAPER_BOX_M, PAPER_BOX_M, PAPER_BOX_M)
    yaw: float = 0.0
    dark: bool = False
    """Its surface returns no depth to the cameras (the sensor model's surfaces that return nothing)."""

    @field_validator("size")
    @classmethod
    def _positive(cls, v: _Vec3) -> _Vec3:
        if min(v) <= 0.0:
            raise ValueError("box sizes must be positive (m)")
        return v


class SceneModel(BaseModel):
    """Schema of a scene YAML file."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    name: str = "scene"
    walls: bool = False
    robot_start: _Vec3 = (0.0, 0.0, 0.0)
    goal: tuple[float, float] | None = None
    metadata: dict[str, float] = {}
    boxes: list[BoxModel] = []

    @field_validator("boxes")
    @classmethod
    def _unique_ids(cls, boxes: list[BoxModel]) -> list[BoxModel]:
        ids = [b.id for b in boxes]
        dup = {i for i in ids if ids.count(i) > 1}
        if dup:
            raise ValueError(f"duplicate box ids: {sorted(dup)}")
        return boxes

    def to_scene(self) -> Scene:
        boxes = tuple(Box(b.id, b.position, b.size, b.yaw, b.dark) for b in self.boxes)
        return Scene(boxes, self.walls, self.robot_start, self.name, self.goal, dict(self.metadata))

    @classmethod
    def from_scene(cls, scene: Scene) -> SceneModel:
        boxes = [BoxModel(id=b.id, position=b.position, size=b.size, yaw=b.yaw, dark=b.dark) for b in scene.boxes]
        return cls(name=scene.name, walls=scene.walls, robot_start=scene.robot_start, goal=scene.goal,
                   metadata=scene.metadata, boxes=boxes)


def load_scene(path: str | Path) -> Scene:
    """Read a scene YAML file; `FileFormatError` names the field and line of every problem."""
    return load_yaml_file(path, SceneModel).to_scene()


def parse_scene(text: str, source: str = "<scene>") -> Scene:
    """Parse scene YAML text (e.g. an upload)."""
    return load_yaml_model(text, SceneModel, source).to_scene()


def scene_to_yaml(scene: Scene) -> str:
    """YAML text of a scene; `parse_scene` reads it back unchanged."""
    return dump_yaml_model(SceneModel.from_scene(scene))


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write a scene YAML file."""
    write_text_atomic(path, scene_to_yaml(scene))


# --- generators ---------------------------------------------------------------------------------

def _passable(boxes: list[Box], start: tuple[float, float], goal: tuple[float, float], clearance_m: float,
              bounds: tuple[float, float, float, float], cell_m: float = 0.05) -> bool:
    """True if a disc of radius `clearance_m` can travel from start to goal between the boxes."""
    x0, x1, y0, y1 = bounds
    xs = np.arange(x0, x1, cell_m)
    ys = np.arange(y0, y1, cell_m)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    blocked = np.zeros(X.shape, bool)
    for b in boxes:
        c, s = math.cos(b.yaw), math.sin(b.yaw)
        dx, dy = X - b.position[0], Y - b.position[1]
        lx, ly = np.abs(c * dx + s * dy) - b.size[0] / 2, np.abs(-s * dx + c * dy) - b.size[1] / 2
        dist = np.hypot(np.maximum(lx, 0), np.maximum(ly, 0)) + np.minimum(np.maximum(lx, ly), 0)
        blocked |= dist < clearance_m
    labels, _ = cast(tuple[np.ndarray, int], ndimage.label(~blocked))

    def cell(p: tuple[float, float]) -> tuple[int, int]:
        return int((p[0] - x0) / cell_m), int((p[1] - y0) / cell_m)

    a, b = labels[cell(start)], labels[cell(goal)]
    return bool(a != 0 and a == b)


def random_scene(seed: int, n_boxes: int = 8, area_m: float = 5.0, two_layers: bool = True,
                 box_m: float = PAPER_BOX_M, clearance_m: float = 0.85, max_tries: int = 2000) -> Scene:
    """The paper's random scene: `n_boxes` boxes of `box_m` in an `area_m` square around the origin.

    The robot starts left of the area facing +x and the goal is right of it. With `two_layers`, some
    boxes are stacked on others. Scenes are resampled until a disc of `clearance_m` can pass (default: the
    base sphere 0.55 m plus delta_safe 0.25 m plus 5 cm, so the controller can get through).
    """
    if n_boxes < 1:
        raise ValueError("a random scene needs at least one box")
    rng = np.random.default_rng(seed)
    half = area_m / 2
    start, goal = (-half - 1.0, 0.0), (half + 1.0, 0.0)
    bounds = (-half - 2.0, half + 2.0, -half - 1.0, half + 1.0)
    for _ in range(max_tries):
        boxes: list[Box] = []
        # a stacked box needs one on the floor below it: at most n_boxes - 1 (same draws as before for n ≥ 2)
        n_stacked = int(rng.integers(0, min(max(1, n_boxes // 3), n_boxes - 1) + 1)) if two_layers else 0
        n_floor = n_boxes - n_stacked
        for _ in range(200 * n_floor):
            if len(boxes) == n_floor:
                break
            x, y = rng.uniform(-half + box_m / 2, half - box_m / 2, size=2)
            yaw = float(rng.uniform(-math.pi / 4, math.pi / 4))
            cand = Box(f"box_{len(boxes)}", (float(x), float(y), box_m / 2), (box_m, box_m, box_m), yaw)
            if all(math.dist(cand.position[:2], b.position[:2]) > 1.5 * box_m for b in boxes):
                boxes.append(cand)
        if len(boxes) < n_floor:
            continue  # too many boxes for the area: try another draw (bounded by max_tries)
        for k in rng.choice(n_floor, size=n_stacked, replace=False) if n_stacked else []:
            below = boxes[int(k)]
            boxes.append(replace(below, id=f"box_{len(boxes)}", position=(*below.position[:2], 1.5 * box_m)))
        if _passable(boxes, start, goal, clearance_m, bounds):
            return Scene(tuple(boxes), robot_start=(*start, 0.0), name=f"random_{seed}", goal=goal,
                         metadata={"seed": float(seed), "area_m": area_m})
    raise SceneGenerationError(f"no passable random scene with {n_boxes} boxes after {max_tries} tries (seed {seed})")


def aisle_scene(length_m: float = 6.0, width_m: float = 3.0, aisle_m: float = 1.9, depth_m: float = PAPER_BOX_M,
                height_m: float = 0.8, segment_m: float = 1.5) -> Scene:
    """A circular aisle: a rectangular ring corridor of width `aisle_m` around an island of boxes.

    Island and outer rows are made of shelf-like boxes of at most `segment_m` long, `depth_m` deep and
    `height_m` tall. The robot starts in the south straight facing +x; laps go counter-clockwise.
    """
    boxes: list[Box] = []

    def row(prefix: str, a: tuple[float, float], b: tuple[float, float]) -> None:
        """Boxes covering the segment a→b (centre line), ends included."""
        span = math.dist(a, b) + depth_m
        n = max(1, math.ceil(span / segment_m))
        seg = span / n
        ux, uy = (b[0] - a[0]) / max(math.dist(a, b), 1e-9), (b[1] - a[1]) / max(math.dist(a, b), 1e-9)
        yaw = math.atan2(uy, ux)
        for i in range(n):
            t = -depth_m / 2 + seg * (i + 0.5)
            centre = (a[0] + t * ux, a[1] + t * uy, height_m / 2)
            boxes.append(Box(f"{prefix}_{i}", centre, (seg, depth_m, height_m), yaw))

    ix, iy = length_m / 2 - depth_m / 2, width_m / 2 - depth_m / 2
    ox, oy = ix + depth_m + aisle_m, iy + depth_m + aisle_m
    row("island_s", (-ix, -iy), (ix, -iy))
    row("island_n", (-ix, iy), (ix, iy))
    row("island_w", (-ix, -iy + depth_m), (-ix, iy - depth_m))
    row("island_e", (ix, -iy + depth_m), (ix, iy - depth_m))
    row("outer_s", (-ox, -oy), (ox, -oy))
    row("outer_n", (-ox, oy), (ox, oy))
    row("outer_w", (-ox, -oy + depth_m), (-ox, oy - depth_m))
    row("outer_e", (ox, -oy + depth_m), (ox, oy - depth_m))
    start = (-length_m / 4, -(iy + depth_m / 2 + aisle_m / 2), 0.0)
    return Scene(tuple(boxes), robot_start=start, name="circular_aisle",
                 metadata={"aisle_m": aisle_m, "length_m": length_m, "width_m": width_m})
