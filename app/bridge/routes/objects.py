"""The objects the map sees, and the operator's names for them (anchored targets refer to these names)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Path, status

from app.bridge.attachment import RuntimeAttachment
from app.bridge.auth import require_token
from app.bridge.dependencies import Attached
from app.bridge.protocol import ErrorOut, MappedObjectOut, NameIn, ObjectsOut
from app.bridge.routes import AUTH_ERRORS, NO_RUNTIME
from app.bridge.views import objects_out
from app.object_names import NameInUseError, NameTakenError, UnknownObjectError
from core.types import vec3

router = APIRouter(prefix="/api/objects", tags=["objects"])
ObjectId = Annotated[str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$")]
REFUSALS: dict[int | str, dict] = {
    404: {"model": ErrorOut, "description": "No object of this id in the map (or it has no name)"},
    409: {"model": ErrorOut, "description": "The name is taken (bound to another object, or the object has another "
                                            "name), or anchored subtasks use it"}}


def _object(attached: RuntimeAttachment, object_id: str) -> MappedObjectOut:
    attached.invalidate()
    found = next((o for o in objects_out(attached.snapshot()).objects if o.id == object_id), None)
    if found is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no object {object_id!r} in the map")
    return found


@router.get("", responses=NO_RUNTIME)
def list_objects(attached: Attached) -> ObjectsOut:
    """The objects the map sees now, each with its name (if any), pose, extent, E[v] and status."""
    return objects_out(attached.snapshot())


@router.put("/{object_id}/name", dependencies=[Depends(require_token)], responses={**AUTH_ERRORS, **REFUSALS})
def name_object(attached: Attached, object_id: ObjectId, body: NameIn) -> MappedObjectOut:
    """Name an object (and declare its full size) for anchored targets; saved with the sequence. Naming it again
    with its own name sets its size."""
    try:
        attached.runtime.name_object(body.name, object_id, None if body.size is None else vec3(body.size))
    except UnknownObjectError as err:
        raise HTTPException(status.HTTP_404_NOT_FOUND, str(err)) from err
    except NameTakenError as err:
        raise HTTPException(status.HTTP_409_CONFLICT, str(err)) from err
    return _object(attached, object_id)


@router.delete("/{object_id}/name", dependencies=[Depends(require_token)], responses={**AUTH_ERRORS, **REFUSALS})
def unname_object(attached: Attached, object_id: ObjectId) -> MappedObjectOut:
    """Take an object's name away (and out of the sequence); refused while anchored subtasks use it."""
    name = _object(attached, object_id).name
    if name is None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"object {object_id!r} has no name")
    try:
        attached.runtime.unname_object(name)
    except (UnknownObjectError, NameInUseError) as err:
        code = status.HTTP_409_CONFLICT if isinstance(err, NameInUseError) else status.HTTP_404_NOT_FOUND
        raise HTTPException(code, str(err)) from err
    return _object(attached, object_id)
