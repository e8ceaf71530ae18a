"""FastAPI dependencies of the operator routes: the robot link, the attached runtime, simulation only.

The server keeps its parts in `app.state` (`token`, `link`, `attachment`); routes receive them
through these functions, as in FastAPI's examples.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, HTTPException, Request, status

from app.bridge.attachment import RuntimeAttachment
from app.bridge.robot_link import RobotLink


def get_link(request: Request) -> RobotLink:
    return request.app.state.link


def get_attachment(request: Request) -> RuntimeAttachment:
    """The attached runtime; 503 while none is attached."""
    attachment: RuntimeAttachment | None = request.app.state.attachment
    if attachment is None:
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, "no runtime is attached to the bridge yet")
    return attachment


def get_simulation(attachment: Annotated[RuntimeAttachment, Depends(get_attachment)]) -> RuntimeAttachment:
    """The attached runtime if it simulates; 409 when it drives a real robot."""
    if not attachment.simulates:
        raise HTTPException(status.HTTP_409_CONFLICT,
                            "this needs the embedded simulation; the runtime drives a robot through the bridge")
    return attachment


Link = Annotated[RobotLink, Depends(get_link)]
Attached = Annotated[RuntimeAttachment, Depends(get_attachment)]
Simulation = Annotated[RuntimeAttachment, Depends(get_simulation)]
