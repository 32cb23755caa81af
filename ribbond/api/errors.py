"""The API's error bodies: one model for every error status, the handlers that produce them, and the
``responses=`` tables that document them in the OpenAPI document (issue 16).

Every error is ``{"detail": str, ...}``; a 422 adds ``errors``, a list of ``{"loc", "msg", "type"}``
(empty when the problem is not one field's), a 409 the job's state and the commands possible now (or
the alignment's refused value), a 403 the refused ``origin``, a 421 the refused ``host``, a 413 the
``limit``. Values the client sent are never echoed whole: a quoted value in a message and a field
name in ``loc`` are cut to 64 characters and "…", a message to 2000.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field, ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import BaseRoute, Match

from ribbond.daemon.components.camera import CameraError
from ribbond.daemon.components.octoprint import UnsupportedFile, UploadRefused
from ribbond.daemon.config import ECHO_MAX, short
from ribbond.daemon.jobs import IllegalTransition
from ribbond.daemon.records import NotFound, ServiceError
from ribbond.gcode.alignment import AlignmentRefused
from ribbond.printer.errors import LinkError, NotReady, PrinterHalted

#: A message is cut to this many characters (a list of names can be long; an echo must not be).
DETAIL_MAX = 2000
#: A quoted value: opened and closed by a quote that is not inside a word (the apostrophe of
#: "daemon's" opens nothing), so prose between two values is never taken for one.
_QUOTED = re.compile(r"(?<!\w)'([^'\n]*)'(?!\w)|(?<!\w)\"([^\"\n]*)\"(?!\w)")


class Error(BaseModel):
    """Every error answer."""

    detail: str = Field(description="what was wrong, for a person")


class ErrorItem(BaseModel):
    """One field's problem."""

    loc: list[str | int] = Field(description="where: 'body', 'query', 'path' or 'header', then the field")
    msg: str
    type: str = Field(description="the kind of problem, e.g. missing, string_too_long, value_error")


class ValidationFailed(Error):
    """422: the request is well-formed but its values are not acceptable."""

    errors: list[ErrorItem] = Field(default_factory=list, description="the fields at fault; empty when the "
                                                                      "problem is not one field's")


class Conflict(Error):
    """409: the job's state (or the printer's, or the alignment) does not allow it now."""

    state: str | None = Field(None, description="the job's state (or the printer's: halted)")
    command: str | None = None
    allowed: list[str] | None = Field(None, description="commands possible in this state")
    allowed_states: list[str] | None = Field(None, description="states the command is possible in")
    refused: str | None = Field(None, description="the alignment check that refused")
    value: float | None = None
    limit: float | None = None


class OriginRefused(Error):
    """403: a state-changing request from a page of another origin."""

    origin: str


class HostRefused(Error):
    """421: the Host header does not name this daemon."""

    host: str


class TooLarge(Error):
    """413: the request body is over ``limits.max_upload_mb``."""

    limit: int = Field(description="bytes")


_STATUS: dict[int, tuple[type[BaseModel], str]] = {
    400: (Error, "the body cannot be parsed (not JSON, not multipart form data)"),
    401: (Error, "no token or a wrong one (when the daemon has a token: Authorization: Bearer <token>)"),
    403: (OriginRefused, "a state-changing request from a page of another origin"),
    404: (Error, "no such job, calibration, table or file (or no camera configured)"),
    409: (Conflict, "the job's or the printer's state does not allow it now (the printer halted: state halted)"),
    413: (TooLarge, "the body is over limits.max_upload_mb"),
    415: (Error, "the file is neither a G-code program nor a mesh the engine reads"),
    421: (HostRefused, "the Host header does not name this daemon (api.allowed_hosts)"),
    422: (ValidationFailed, "the values are not acceptable"),
    502: (Error, "the camera did not answer, or not with JPEG images"),
    503: (Error, "the printer is not connected"),
}


def responses(*codes: int, mutating: bool = False, body: bool = False) -> dict[int | str, dict[str, Any]]:
    """The ``responses=`` of a route: ``codes`` plus the gate's (401, 421; 403 when ``mutating``;
    400, 413 and 422 when it takes a body)."""
    wanted = {401, 421, *codes} | ({403} if mutating else set()) | ({400, 413, 422} if body else set())
    out: dict[int | str, dict[str, Any]] = {}
    for code in sorted(wanted):
        model, text = _STATUS[code]
        out[code] = {"model": model, "description": text}
    out[401]["headers"] = {"WWW-Authenticate": {"schema": {"type": "string"}, "description": "Bearer"}}
    return out


def bounded(text: str) -> str:
    """``text`` with every quoted value over 64 characters cut, and at most 2000 characters, cut
    after a whole word."""
    text = _QUOTED.sub(_cut_value, text)
    return cut_at_word(text, DETAIL_MAX)


def _cut_value(match: re.Match[str]) -> str:
    value = match.group(1) if match.group(1) is not None else match.group(2)
    return repr(short(value)) if len(value) > ECHO_MAX else match.group(0)


def cut_at_word(text: str, limit: int) -> str:
    """``text`` if it has at most ``limit`` characters, else its words that fit and "…" (a single
    word longer than the limit is cut: it is a value, not prose)."""
    if len(text) <= limit:
        return text
    head = text[:limit]
    space = head.rfind(" ")
    return (head[:space].rstrip() if space > limit // 2 else head) + " …"


def _items(errors: list[dict[str, Any]], prefix: tuple[str | int, ...] = ()) -> list[dict[str, Any]]:
    return [{"loc": [*prefix, *(short(p) if isinstance(p, str) else p for p in e.get("loc", ()))],
             "msg": bounded(str(e.get("msg", ""))), "type": str(e.get("type", "value_error"))} for e in errors]


def _summary(items: list[dict[str, Any]]) -> str:
    return bounded("; ".join(f"{'.'.join(map(str, i['loc'])) or '(request)'}: {i['msg']}" for i in items))


def _json(status: int, body: dict[str, Any], headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse(status_code=status, content=body, headers=headers)


def install(app: FastAPI) -> None:
    """The exception handlers: each error as its documented model."""

    @app.exception_handler(RequestValidationError)
    async def _request(_: Request, exc: RequestValidationError) -> JSONResponse:
        items = _items(list(exc.errors()))
        return _json(422, {"detail": _summary(items), "errors": items})

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        headers = dict(exc.headers or {})
        if exc.status_code == 405:                  # every method of the path, not one route's
            headers["Allow"] = ", ".join(sorted(_methods(app, request)))
        return _json(exc.status_code, {"detail": bounded(str(exc.detail))}, headers)

    @app.exception_handler(IllegalTransition)
    async def _illegal(_: Request, exc: IllegalTransition) -> JSONResponse:
        return _json(409, {"detail": bounded(str(exc)), "state": exc.current.value, "command": exc.command,
                           "allowed": list(exc.allowed), "allowed_states": list(exc.allowed_states)})

    @app.exception_handler(AlignmentRefused)
    async def _refused(_: Request, exc: AlignmentRefused) -> JSONResponse:
        return _json(409, {"detail": bounded(str(exc)), "refused": exc.which, "value": exc.value,
                           "limit": exc.limit})

    @app.exception_handler(NotFound)
    async def _missing(_: Request, exc: NotFound) -> JSONResponse:
        return _json(404, {"detail": bounded(str(exc))})

    @app.exception_handler(ServiceError)
    async def _conflict(_: Request, exc: ServiceError) -> JSONResponse:
        return _json(409, {"detail": bounded(str(exc))})

    @app.exception_handler(LinkError)
    async def _printer(_: Request, exc: LinkError) -> JSONResponse:
        if halted(exc):                             # a state of the printer's, as a job's state is: 409
            text = str(exc) if isinstance(exc, PrinterHalted) else "the printer is halted: ribbonctl recover"
            return _json(409, {"detail": bounded(f"printer: {text}"), "state": "halted", "allowed": ["recover"]})
        return _json(503, {"detail": bounded(f"printer: {exc}")})

    @app.exception_handler(UploadRefused)
    async def _upload(_: Request, exc: UploadRefused) -> JSONResponse:
        # a slicer's upload (OctoPrint's statuses): the file's type 415, anything else about it 400
        return _json(415 if isinstance(exc, UnsupportedFile) else 400, {"detail": bounded(str(exc))})

    @app.exception_handler(CameraError)
    async def _camera(_: Request, exc: CameraError) -> JSONResponse:
        return _json(502, {"detail": bounded(f"camera: {exc}")})

    @app.exception_handler(ValueError)
    async def _invalid(_: Request, exc: ValueError) -> JSONResponse:
        if isinstance(exc, ValidationError):        # a model checked in the service: its fields
            items = _items(exc.errors(include_url=False, include_input=False))
            return _json(422, {"detail": bounded(f"{exc.title}: {_summary(items)}"), "errors": items})
        # a refusal that knows its fields (design parameters) lists them; others name them in words
        fields = getattr(exc, "errors", None)
        items = _items(fields) if isinstance(fields, list) else []
        return _json(422, {"detail": bounded(str(exc)), "errors": items})


def halted(exc: LinkError) -> bool:
    """The request was refused because the printer is halted (not because it is away)."""
    return isinstance(exc, PrinterHalted) or (isinstance(exc, NotReady) and exc.state == "halted")


def _methods(app: FastAPI, request: Request) -> set[str]:
    methods: set[str] = set()
    for route in _leaves(app.router.routes):
        match, _ = route.matches(request.scope)
        if match is not Match.NONE:
            methods |= set(getattr(route, "methods", None) or ())
    return methods


def _leaves(routes: Iterable[BaseRoute]) -> Iterator[BaseRoute]:
    """The routes themselves: newer FastAPI keeps an included router whole (``original_router``,
    which has no methods) where older ones copied its routes; the routers are mounted unprefixed."""
    for route in routes:
        included = getattr(route, "original_router", None)
        if included is None:
            yield route
        else:
            yield from _leaves(included.routes)
