"""Exception handlers: every error the operator API returns has the `ErrorOut` shape.

A request that does not follow its schema, a rejected sequence file and a refused scene edit are 422
with the problems listed (a sequence's with field and line); other HTTP errors keep their status.
"""

from __future__ import annotations

import logging

from fastapi import FastAPI, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from app.bridge.protocol import ErrorOut, Problem
from core.sim.world import SceneEditError
from core.yaml_validation import FileFormatError

log = logging.getLogger(__name__)


def file_problems(err: FileFormatError) -> list[Problem]:
    """The problems of a rejected file: field, line, message."""
    return [Problem(field=field, line=line, message=message) for field, line, message in err.problems]


def _reply(status_code: int, detail: str, problems: list[Problem] | None = None) -> JSONResponse:
    return JSONResponse(ErrorOut(detail=detail, problems=problems or []).model_dump(mode="json"), status_code)


async def _invalid_request(_: Request, err: RequestValidationError) -> JSONResponse:
    problems = [Problem(field=".".join(str(x) for x in e.get("loc", ())), line=None, message=str(e.get("msg", "")))
                for e in err.errors()]
    return _reply(status.HTTP_422_UNPROCESSABLE_CONTENT, "the request does not follow its schema", problems)


async def _bad_file(_: Request, err: FileFormatError) -> JSONResponse:
    return _reply(status.HTTP_422_UNPROCESSABLE_CONTENT, str(err).splitlines()[0], file_problems(err))


async def _refused_edit(_: Request, err: SceneEditError) -> JSONResponse:
    log.info("scene edit refused: %s", err)
    return _reply(status.HTTP_422_UNPROCESSABLE_CONTENT, str(err))


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers on `app`."""
    app.add_exception_handler(RequestValidationError, _invalid_request)
    app.add_exception_handler(FileFormatError, _bad_file)
    app.add_exception_handler(SceneEditError, _refused_edit)
