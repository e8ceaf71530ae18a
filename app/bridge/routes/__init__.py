"""The operator API, one router per resource: status (health, state, plan, progress), run control,
the task sequence and the simulated scene. Every route that changes anything needs the bearer token."""

from __future__ import annotations

from app.bridge.protocol import ErrorOut

NO_RUNTIME: dict[int | str, dict] = {503: {"model": ErrorOut, "description": "No runtime is attached to the bridge"}}
"""Error response of every route that needs an attached runtime."""
AUTH_ERRORS: dict[int | str, dict] = {
    400: {"model": ErrorOut, "description": "The body is not JSON"},
    401: {"model": ErrorOut, "description": "Missing or wrong bearer token"},
    422: {"model": ErrorOut, "description": "The request does not follow its schema"},
    **NO_RUNTIME,
}
"""Error responses of every protected route."""
CONFLICT: dict[int | str, dict] = {409: {"model": ErrorOut, "description": "Not possible in the runtime's state"}}
