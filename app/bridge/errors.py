"""Exception handlers: every error the operator API returns has the `ErrorOut` shape.

A body that is not JSON is 400; a request that does not follow its schema, a rejected sequence file
and a refused scene edit are 422 with the problems listed (a sequence's with field and line); other
HTTP errors keep their status; anything unexpected is a 500 in the same shape (the traceback goes to
the log, not to the client).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

from fastapi import FastAPI, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.bridge.protocol import ErrorOut, Problem
from core.sim.world import SceneEditError
from core.yaml_validation import FileFormatError

log = logging.getLogger(__name__)


def file_problems(err: FileFormatError) -> list[Problem]:
    """The problems of a rejected file: field, line, message."""
    return [Problem(field=field, line=line, message=message) for field, line, message in err.problems]


def _reply(status_code: int, detail: str, problems: list[Problem] | None = None,
           headers: Mapping[str, str] | None = None) -> JSONResponse:
    return JSONResponse(ErrorOut(detail=detail, problems=problems or []).model_dump(mode="json"), status_code,
                        headers=headers)


def _json_media_type(content_type: str) -> bool:
    media = content_type.split(";", 1)[0].strip().lower()
    return media == "application/json" or (media.startswith("application/") and media.endswith("+json"))


def _body_not_json(request: Request, err: RequestValidationError) -> bool:
    """The body failed to parse as JSON, or came with a content type that is not JSON."""
    if any(e.get("type") == "json_invalid" for e in err.errors()):
        return True
    has_body = request.headers.get("content-length", "0") not in ("", "0") or "transfer-encoding" in request.headers
    about_body = any(tuple(e.get("loc", ()))[:1] == ("body",) for e in err.errors())
    return has_body and about_body and not _json_media_type(request.headers.get("content-type", ""))


async def _invalid_request(request: Request, err: RequestValidationError) -> JSONResponse:
    problems = [Problem(field=".".join(str(x) for x in e.get("loc", ())), line=None, message=str(e.get("msg", "")))
                for e in err.errors()]
    if _body_not_json(request, err):
        return _reply(status.HTTP_400_BAD_REQUEST, "the body is not JSON (send Content-Type: application/json)",
                      problems)
    return _reply(status.HTTP_422_UNPROCESSABLE_CONTENT, "the request does not follow its schema", problems)


async def _http_error(_: Request, err: HTTPException) -> JSONResponse:
    return _reply(err.status_code, str(err.detail), headers=err.headers)


async def _bad_file(_: Request, err: FileFormatError) -> JSONResponse:
    return _reply(status.HTTP_422_UNPROCESSABLE_CONTENT, str(err).splitlines()[0], file_problems(err))


async def _refused_edit(_: Request, err: SceneEditError) -> JSONResponse:
    log.info("scene edit refused: %s", err)
    return _reply(status.HTTP_422_UNPROCESSABLE_CONTENT, str(err))


class InternalErrorMiddleware:
    """Last resort: an unexpected exception becomes a 500 in the documented shape, not plain text.

    A plain ASGI middleware rather than an `Exception` handler: Starlette re-raises after such a handler
    and uvicorn then drops the connection, so clients could see a reset instead of the answer. The
    traceback goes to the log; the client learns the exception's type and the route, nothing more.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def tracked(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive, tracked)
        except Exception as err:
            log.exception("internal error in %s %s", scope.get("method"), scope.get("path"))
            if started:
                raise
            detail = f"internal error ({type(err).__name__}) in {scope.get('method')} {scope.get('path')}; " \
                     "see the studio's log"
            await _reply(status.HTTP_500_INTERNAL_SERVER_ERROR, detail)(scope, receive, send)


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers (and the last-resort middleware) on `app`."""
    app.exception_handler(RequestValidationError)(_invalid_request)
    app.exception_handler(HTTPException)(_http_error)
    app.add_middleware(InternalErrorMiddleware)
    app.exception_handler(FileFormatError)(_bad_file)
    app.exception_handler(SceneEditError)(_refused_edit)
