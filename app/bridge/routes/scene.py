"""Scene edits while the robot works (only when the runtime simulates; 409 when it drives a robot)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Path, status

from app.bridge.attachment import RuntimeAttachment
from app.bridge.auth import require_token
from app.bridge.dependencies import Simulation
from app.bridge.protocol import BoxIn, BoxMoveIn, BoxOut, ErrorOut, RandomiseIn, SceneOut
from app.bridge.routes import AUTH_ERRORS, CONFLICT, NO_RUNTIME
from app.bridge.views import scene_out
from core.scene import Box
from core.types import vec3

router = APIRouter(prefix="/api/scene", tags=["scene"])
NOT_FOUND = {404: {"model": ErrorOut, "description": "No box with this id"}}
PROTECTED = {"dependencies": [Depends(require_token)], "responses": {**AUTH_ERRORS, **CONFLICT}}
PROTECTED_BOX = {"dependencies": [Depends(require_token)], "responses": {**AUTH_ERRORS, **CONFLICT, **NOT_FOUND}}
BoxId = Annotated[str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$")]


def _box_out(box: Box) -> BoxOut:
    return BoxOut(id=box.id, position=list(box.position), size=list(box.size), yaw=box.yaw)


def _existing(sim: RuntimeAttachment, box_id: str) -> str:
    if box_id not in {b.id for b in sim.runtime.scene().boxes}:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no box {box_id!r}")
    return box_id


@router.get("", responses={**CONFLICT, **NO_RUNTIME})
def get_scene(sim: Simulation) -> SceneOut:
    """The boxes of the simulated scene and the robot's base pose."""
    return scene_out(sim.runtime.scene())


@router.post("/boxes", status_code=status.HTTP_201_CREATED, **PROTECTED)
def add_box(sim: Simulation, body: BoxIn) -> BoxOut:
    """Add a box (422 if its id exists or it would overlap the robot)."""
    box = Box(body.id, vec3(body.position), vec3(body.size), body.yaw)
    sim.runtime.add_box(box)
    return _box_out(box)


@router.put("/boxes/{box_id}", **PROTECTED_BOX)
def move_box(sim: Simulation, box_id: BoxId, body: BoxMoveIn) -> BoxOut:
    """Move a box (422 if it would overlap the robot; nothing changes then)."""
    return _box_out(sim.runtime.move_box(_existing(sim, box_id), vec3(body.position), body.yaw))


@router.delete("/boxes/{box_id}", **PROTECTED_BOX)
def remove_box(sim: Simulation, box_id: BoxId) -> BoxOut:
    """Remove a box; returns it."""
    return _box_out(sim.runtime.remove_box(_existing(sim, box_id)))


@router.post("/randomise", **PROTECTED)
def randomise(sim: Simulation, body: RandomiseIn) -> SceneOut:
    """The paper's random scene from a seed; the robot goes back to its start and the map restarts."""
    sim.invalidate()
    return scene_out(sim.runtime.randomise_scene(body.seed, body.n_boxes))
