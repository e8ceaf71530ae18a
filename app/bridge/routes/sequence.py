"""The task sequence: read it, validate YAML text, load it (errors name field and line)."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request

from app.bridge.auth import require_token
from app.bridge.dependencies import Attached
from app.bridge.errors import file_problems
from app.bridge.protocol import SequenceIn, SequenceOut, ValidationOut
from app.bridge.routes import AUTH_ERRORS, NO_RUNTIME
from app.target_check import check_targets
from tasks.schema import TaskSequence
from tasks.sequence_file import FileFormatError, parse_sequence, sequence_to_yaml

router = APIRouter(prefix="/api/sequence", tags=["sequence"])


def _out(sequence: TaskSequence, version: int, warnings: list[str] | None = None) -> SequenceOut:
    return SequenceOut(name=sequence.name, version=version, subtasks=len(sequence.subtasks),
                       yaml=sequence_to_yaml(sequence), warnings=warnings or [])


@router.get("", responses=NO_RUNTIME)
def get_sequence(attached: Attached) -> SequenceOut:
    """The authored sequence (YAML) and its version (counts loads)."""
    runtime = attached.runtime
    return _out(runtime.sequence, runtime.sequence_version)


@router.post("/validate", dependencies=[Depends(require_token)],
             responses={k: v for k, v in AUTH_ERRORS.items() if k != 503})
def validate(request: Request, body: SequenceIn) -> ValidationOut:
    """Check YAML text against the sequence schema, and its targets against the robot and the attached runtime's
    scene (without a runtime, the schema only), without loading it."""
    attachment = request.app.state.attachment
    try:
        sequence = parse_sequence(body.yaml, "request")
        warnings = [] if attachment is None else check_targets(
            attachment.runtime, sequence, scene_may_change=body.scene_may_change, source="request", text=body.yaml)
    except FileFormatError as err:  # a TargetError is one too
        return ValidationOut(valid=False, problems=file_problems(err))
    return ValidationOut(valid=True, name=sequence.name, subtasks=len(sequence.subtasks),
                         warnings=[str(w) for w in warnings])


@router.put("", dependencies=[Depends(require_token)], responses=AUTH_ERRORS)
def load(attached: Attached, body: SequenceIn) -> SequenceOut:
    """Load YAML text as the authored sequence (a run under way, running or paused/stopped mid-sequence, keeps its
    copy to its end).

    422 lists every problem with its field and line (schema, and targets the robot cannot reach or that are too
    close to a box, each with the nearest acceptable value); nothing is loaded then."""
    sequence = parse_sequence(body.yaml, "request")
    warnings = attached.runtime.set_sequence(sequence, scene_may_change=body.scene_may_change, source="request",
                                             text=body.yaml)
    attached.invalidate()
    return _out(sequence, attached.runtime.sequence_version, [str(w) for w in warnings])
