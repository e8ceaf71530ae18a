"""Run control: start, pause, step, stop, reset, emergency stop, and the map/constraint/speed settings."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated

from fastapi import APIRouter, Body, Depends, HTTPException, Request, status

from app.bridge.attachment import RuntimeAttachment
from app.bridge.auth import require_token
from app.bridge.dependencies import Attached, Link
from app.bridge.protocol import ConfigIn, RunStatus, StepIn
from app.bridge.routes import AUTH_ERRORS, CONFLICT
from app.runtime.closed_loop import FaultError
from app.runtime.snapshot import RunState

if TYPE_CHECKING:
    from app.runtime import Runtime

router = APIRouter(prefix="/api/run", tags=["run control"], dependencies=[Depends(require_token)],
                   responses=AUTH_ERRORS)


def _status(attached: RuntimeAttachment) -> RunStatus:
    attached.invalidate()
    runtime = attached.runtime
    return RunStatus(run_state=runtime.run_state.value, status=runtime.status_line(), fault=runtime.fault)


def _conflict(detail: str) -> HTTPException:
    return HTTPException(status.HTTP_409_CONFLICT, detail)


@router.post("/start", responses=CONFLICT)
def start(request: Request, attached: Attached, link: Link) -> RunStatus:
    """Run the sequence from its first subtask, or resume a paused run. 409 without fresh robot state, and
    while the run is faulted (the detail says why; reset first)."""
    if attached.runtime.backend is request.app.state.robot and link.is_stale():
        raise _conflict("no fresh robot state: is the driver connected and streaming?")
    try:
        attached.runtime.start()
    except FaultError as err:
        raise _conflict(str(err)) from err
    return _status(attached)


def _command(name: str, act: Callable[[Runtime], None], doc: str) -> Callable[[RuntimeAttachment], RunStatus]:
    """A run-control route that needs no precondition: do `act` on the runtime, answer the run's status."""

    def route(attached: Attached) -> RunStatus:
        act(attached.runtime)
        return _status(attached)

    route.__name__ = route.__qualname__ = name  # FastAPI names the operation after the function
    route.__doc__ = doc
    return route


router.post("/pause")(_command("pause", lambda rt: rt.pause(),
                               "Pause: the simulation freezes; a real robot holds still."))


@router.post("/step", responses=CONFLICT)
def step(attached: Attached, body: Annotated[StepIn | None, Body()] = None) -> RunStatus:
    """While paused, advance the simulation by one control period (or `seconds`)."""
    if not attached.steps:
        raise _conflict("step needs a backend the runtime steps (the embedded simulation)")
    if attached.runtime.run_state != RunState.PAUSED:
        raise _conflict("step works while paused")
    attached.runtime.step(None if body is None else body.seconds)
    return _status(attached)


@router.post("/skip", responses=CONFLICT)
def skip(attached: Attached) -> RunStatus:
    """Skip the active subtask (one with no path to its goal, say); the run goes on with the next one. 409 when
    no subtask is active."""
    try:
        attached.runtime.skip()
    except ValueError as err:
        raise _conflict(str(err)) from err
    return _status(attached)


router.post("/stop")(_command("stop", lambda rt: rt.stop(), "Stop the sequence; the robot comes to rest."))
router.post("/reset")(_command("reset", lambda rt: rt.reset(),
                               "Reload the scene (simulation: robot back at its start), clear map, plan, progress "
                               "and a fault."))
router.post("/emergency-stop")(_command("emergency_stop", lambda rt: rt.emergency_stop(),
                                        "Zero velocity at once; nothing moves until start or reset."))


@router.post("/config", responses=CONFLICT)
def configure(attached: Attached, body: ConfigIn) -> RunStatus:
    """Switch the map kind or constraint kind (takes effect now) or the live speed (simulation only)."""
    if body.speed is not None and not attached.steps:
        raise _conflict("speed needs a backend the runtime steps (the embedded simulation)")
    if body.map_kind == "ground_truth" and not attached.simulates:
        raise _conflict("the ground-truth map needs the embedded simulation")
    if body.map_kind or body.constraint:
        attached.runtime.configure(map_kind=body.map_kind, constraint=body.constraint)
    if body.speed is not None:
        attached.runtime.set_speed(body.speed)
    return _status(attached)
