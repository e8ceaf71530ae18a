"""Read-only status: health (no runtime needed), robot state, current plan, sequence progress."""

from __future__ import annotations

from fastapi import APIRouter, Request

from app.bridge.dependencies import Attached, Link
from app.bridge.protocol import Health, PlanResponse, ProgressOut, RobotStateOut
from app.bridge.routes import NO_RUNTIME
from app.bridge.views import health_out, plan_out, progress_out, state_out

router = APIRouter(prefix="/api", tags=["status"])


@router.get("/health")
def health(request: Request, link: Link) -> Health:
    """Bridge alive; driver connected and how old its state is; counters of the link and rejections."""
    return health_out(link, request.app.state.attachment)


@router.get("/state", responses=NO_RUNTIME)
def state(attached: Attached) -> RobotStateOut:
    """The robot's joint state as the runtime sees it, with the run state."""
    return state_out(attached.snapshot())


@router.get("/plan", responses=NO_RUNTIME)
def plan(attached: Attached) -> PlanResponse:
    """The active HTMPC plan (null when there is none)."""
    snap = attached.snapshot()
    return PlanResponse(run_state=snap.run_state.value, plan=None if snap.plan is None else plan_out(snap.plan))


@router.get("/progress", responses=NO_RUNTIME)
def progress(attached: Attached) -> ProgressOut:
    """Progress of the sequence: each subtask's outcome and errors."""
    return progress_out(attached.snapshot())
