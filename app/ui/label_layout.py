"""Where mapped objects' labels go so that they never print over each other: stacked in height where objects
stand together (two boxes on one table), then, seen through the operator's camera, each label that would still
cover one placed before it is moved up the screen, a line at a time, until it covers none (objects far apart
in the room line up along the view, and a label is wider on the screen than its box)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

LABEL_STACK_M = 0.22
"""Labels whose anchors lie within `LABEL_NEAR_M` of each other are stacked this far apart in height."""
LABEL_NEAR_M = 0.8
CHAR_PX = 7.0
"""Width of a label's character on the page (px; viser's labels are drawn at a fixed screen size)."""
PAD_PX = 12.0
LINE_PX = 20.0
"""Height of a label on the page (px), and the step a covered label moves up by."""
MAX_LINES = 24
"""A label moves up at most this many lines (a crowd beyond it is left as it is)."""


def stacked(anchors: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Label positions apart in the room: each anchor raised by `LABEL_STACK_M` until no label placed before it is
    within `LABEL_NEAR_M` in the plane and `LABEL_STACK_M` in height (placed in the anchors' order)."""
    placed: list[np.ndarray] = []
    for anchor in anchors:
        p = np.asarray(anchor, float).copy()
        while any(np.hypot(*(p[:2] - q[:2])) < LABEL_NEAR_M and abs(p[2] - q[2]) < LABEL_STACK_M - 1e-9
                  for q in placed):
            p[2] += LABEL_STACK_M
        placed.append(p)
    return placed


@dataclass(frozen=True)
class FixedLabel:
    """A label another panel draws (a subtask's goal) that the map's labels keep clear of: its position (m) in the
    world, or in the robot's base frame when `on_base` (it moves with the robot), and its text."""

    position: np.ndarray
    text: str
    on_base: bool = False

    def world(self, T_world_base: np.ndarray) -> np.ndarray:
        """Its position in the world, the base at `T_world_base` (4×4)."""
        p = np.asarray(self.position, float)
        return T_world_base[:3, :3] @ p + T_world_base[:3, 3] if self.on_base else p


@dataclass(frozen=True)
class View:
    """A browser's camera as viser reports it: where it is, what it looks at, its vertical field of view (rad)
    and the page's canvas in pixels."""

    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float
    width_px: float
    height_px: float

    @staticmethod
    def of(camera) -> View | None:
        """The view of a viser `CameraHandle` (None before the page reported its canvas)."""
        w, h = float(camera.image_width or 0), float(camera.image_height or 0)
        if w <= 0 or h <= 0 or not np.isfinite(camera.fov) or camera.fov <= 0:
            return None
        return View(np.asarray(camera.position, float), np.asarray(camera.look_at, float),
                    np.asarray(camera.up_direction, float), float(camera.fov), w, h)

    def _basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f = self.look_at - self.position
        f = f / np.linalg.norm(f)
        r = np.cross(f, self.up)
        r = r / np.linalg.norm(r)
        return f, r, np.cross(r, f)

    def pixel(self, point: np.ndarray) -> tuple[float, float] | None:
        """Page pixel (x right, y down) of a world point; None behind the camera."""
        f, r, u = self._basis()
        d = np.asarray(point, float) - self.position
        depth = float(d @ f)
        if depth <= 1e-6:
            return None
        t = np.tan(self.fov / 2)
        x, y = float(d @ r) / (depth * t * self.width_px / self.height_px), float(d @ u) / (depth * t)
        return (x + 1) / 2 * self.width_px, (1 - y) / 2 * self.height_px

    def up_one_line(self, point: np.ndarray) -> np.ndarray:
        """The world step that moves a label at `point` one line (`LINE_PX`) up the page."""
        f, _, u = self._basis()
        depth = max(float((np.asarray(point, float) - self.position) @ f), 1e-3)
        metres_per_px = 2 * depth * np.tan(self.fov / 2) / self.height_px
        return u * LINE_PX * metres_per_px


def _box(view: View, point: np.ndarray, text: str) -> tuple[float, float, float, float] | None:
    """The page rectangle (x0, y0, x1, y1) a label anchored at its top-left corner covers."""
    px = view.pixel(point)
    if px is None:
        return None
    return px[0], px[1], px[0] + CHAR_PX * len(text) + PAD_PX, px[1] + LINE_PX


def _covers(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def screen_stacked(anchors: Sequence[np.ndarray], texts: Sequence[str], view: View | None,
                   fixed: Sequence[tuple[np.ndarray, str]] = ()) -> list[np.ndarray]:
    """The anchors, each moved up the page a line at a time while its label would cover one placed before it
    (placed in order) or one of the `fixed` labels (position, text: drawn by someone else, they do not move);
    unchanged without a view."""
    out = [np.asarray(a, float).copy() for a in anchors]
    if view is None:
        return out
    boxes = [b for b in (_box(view, np.asarray(p, float), t) for p, t in fixed) if b is not None]
    for p, text in zip(out, texts, strict=True):
        box = _box(view, p, text)
        for _ in range(MAX_LINES):
            if box is None or not any(_covers(box, b) for b in boxes):
                break
            p += view.up_one_line(p)
            box = _box(view, p, text)
        if box is not None:
            boxes.append(box)
    return out


def any_overprint(anchors: Sequence[np.ndarray], texts: Sequence[str], view: View) -> bool:
    """Whether two labels would cover each other on the page."""
    boxes = [b for b in (_box(view, np.asarray(a, float), t) for a, t in zip(anchors, texts, strict=True))
             if b is not None]
    return any(_covers(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
