"""The REST API: routes onto ``RibbonService`` methods, pydantic models in and out, no business logic.

OpenAPI at ``/docs``. Errors: an illegal request for the job's state is 409 with the state and what
is allowed; an unknown job or file 404; bad input 422; an upload over the limit 413; the printer
not connected 503. When a token is configured (always when listening beyond loopback), every route
but the documentation needs ``Authorization: Bearer <token>``, compared in constant time.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import tempfile
from pathlib import Path
from typing import Annotated, Any

from fastapi import Depends, FastAPI, File, Form, HTTPException, Request, UploadFile
from fastapi.responses import FileResponse, JSONResponse, StreamingResponse
from pydantic import BaseModel, Field

from .alignment import AlignmentRefused
from .config import tokens_match
from .jobs import IllegalTransition
from .printer.errors import LinkError
from .service import NotFound, RibbonService, ServiceError
from .store import JobRecord, Transition

#: Files of a job that can be fetched.
JOB_FILES = {"preview.png": "design", "preview.svg": "design", "design.json": "design",
             "front.gcode": "design", "back.gcode": "design", "combined.gcode": "design",
             "target.obj": "design", "flat.obj": "design", "back-corrected.gcode": "job"}
_CHUNK = 1 << 20


class JobStatus(JobRecord):
    """A job as the API shows it: the stored record and, while it streams, the time left."""

    eta_s: float | None = Field(None, description="seconds left of the program being streamed")


class BodyLimit:
    """ASGI middleware: a request body larger than ``limit`` bytes is answered 413 as soon as it
    passes the limit, whether or not it announced its length (the multipart parser would otherwise
    spool a chunked upload to disk whole before the route sees it)."""

    def __init__(self, app: Any, limit: int) -> None:
        self.app, self.limit = app, limit

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length", b"")
        if length.isdigit() and int(length) > self.limit:
            await self._refuse(send, int(length))
            return
        seen = 0
        refused = False

        async def counted() -> dict[str, Any]:
            nonlocal seen, refused
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.limit:
                refused = True
                raise _TooLarge()
            return message

        try:
            await self.app(scope, counted, send)
        except _TooLarge:
            await self._refuse(send, seen)
        except Exception:
            if not refused:
                raise
            await self._refuse(send, seen)

    async def _refuse(self, send: Any, size: int) -> None:
        body = json.dumps({"detail": f"upload of {size} bytes or more exceeds the limit of {self.limit} "
                                     "bytes (limits.max_upload_mb)"}).encode()
        with contextlib.suppress(Exception):
            await send({"type": "http.response.start", "status": 413,
                        "headers": [(b"content-type", b"application/json"), (b"connection", b"close"),
                                    (b"content-length", str(len(body)).encode())]})
            await send({"type": "http.response.body", "body": body})


class _TooLarge(Exception):
    pass


class AlignRequest(BaseModel):
    """Confirm a registration mark (no jog) or report the jog that put the head on it."""

    mark: int = Field(ge=0, description="the mark's index (0-based, as in design.json)")
    jog: tuple[float, float] | None = Field(None, description="(dx, dy) mm the head was moved to sit on the mark")


def create_app(service: RibbonService, token: str | None) -> FastAPI:
    """The FastAPI application over ``service``; ``token`` None means no authentication."""
    app = FastAPI(title="ribbond", version="1", description=__doc__)
    limit = int(service.config.limits.max_upload_mb * 1024 * 1024)

    async def authorize(request: Request) -> None:
        if token is None:
            return
        header = request.headers.get("authorization", "")
        given = header[7:] if header.lower().startswith("bearer ") else None
        if not tokens_match(given, token):
            raise HTTPException(401, "missing or wrong API token (Authorization: Bearer <token>)",
                                headers={"WWW-Authenticate": "Bearer"})

    auth = [Depends(authorize)]

    @app.exception_handler(IllegalTransition)
    async def _illegal(_: Request, exc: IllegalTransition) -> JSONResponse:
        return JSONResponse(status_code=409, content={"detail": str(exc), "state": exc.current.value,
                                                      "allowed": exc.allowed})

    @app.exception_handler(NotFound)
    async def _missing(_: Request, exc: NotFound) -> JSONResponse:
        return JSONResponse(status_code=404, content={"detail": str(exc)})

    @app.exception_handler(AlignmentRefused)
    async def _refused(_: Request, exc: AlignmentRefused) -> JSONResponse:
        return JSONResponse(status_code=409, content={"detail": str(exc), "refused": exc.which,
                                                      "value": exc.value, "limit": exc.limit})

    @app.exception_handler(ServiceError)
    async def _conflict(_: Request, exc: ServiceError) -> JSONResponse:
        return JSONResponse(status_code=409, content={"detail": str(exc)})

    @app.exception_handler(LinkError)
    async def _printer(_: Request, exc: LinkError) -> JSONResponse:
        return JSONResponse(status_code=503, content={"detail": f"printer: {exc}"})

    @app.exception_handler(ValueError)
    async def _invalid(_: Request, exc: ValueError) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": str(exc)})

    @app.post("/jobs", status_code=201, response_model=JobRecord, dependencies=auth)
    async def submit(mesh: Annotated[UploadFile, File(description="OBJ, PLY, STL or OFF")],
                     parameters: Annotated[str, Form(description="design parameters, JSON")] = "{}",
                     start: Annotated[bool, Form(description="print as soon as compiled")] = False) -> JobRecord:
        try:
            params = json.loads(parameters)
        except ValueError as exc:
            raise ValueError(f"parameters: not valid JSON: {exc}") from None
        if not isinstance(params, dict):
            raise ValueError("parameters: expected a JSON object")
        uploads = Path(service.config.state_dir) / "uploads"
        uploads.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(dir=uploads, prefix="upload-")
        tmp = Path(tmp_name)
        size = 0
        try:
            with open(fd, "wb") as out:
                while chunk := await mesh.read(_CHUNK):
                    size += len(chunk)
                    if size > limit:
                        raise HTTPException(413, f"upload exceeds the limit of {limit} bytes (limits.max_upload_mb)")
                    out.write(chunk)
            return service.submit(tmp, mesh.filename or "mesh.obj", params, start)
        finally:
            tmp.unlink(missing_ok=True)

    @app.get("/jobs", response_model=list[JobRecord], dependencies=auth)
    async def jobs() -> list[JobRecord]:
        return service.jobs()

    @app.get("/jobs/{job_id}", response_model=JobStatus, dependencies=auth)
    async def job(job_id: str) -> JobStatus:
        return JobStatus(**service.job(job_id).model_dump(), eta_s=service.eta(job_id))

    @app.get("/jobs/{job_id}/transitions", response_model=list[Transition], dependencies=auth)
    async def transitions(job_id: str) -> list[Transition]:
        service.job(job_id)
        return service.store.transitions(job_id)

    @app.get("/jobs/{job_id}/files/{name}", dependencies=auth)
    async def job_file(job_id: str, name: str) -> FileResponse:
        record = service.job(job_id)
        where = JOB_FILES.get(name)
        if where is None:
            raise NotFound(f"{name!r} is not a job file; files: {', '.join(JOB_FILES)}")
        base = Path(record.design_dir) if where == "design" and record.design_dir else service.job_dir(job_id)
        path = base / name
        if not path.is_file():
            raise NotFound(f"job {job_id} has no {name} (yet)")
        return FileResponse(path)

    @app.post("/jobs/{job_id}/start", response_model=JobRecord, dependencies=auth)
    async def start(job_id: str) -> JobRecord:
        return service.start_job(job_id)

    @app.post("/jobs/{job_id}/pause", response_model=JobRecord, dependencies=auth)
    async def pause(job_id: str) -> JobRecord:
        return await service.pause(job_id)

    @app.post("/jobs/{job_id}/resume", response_model=JobRecord, dependencies=auth)
    async def resume(job_id: str) -> JobRecord:
        return await service.resume(job_id)

    @app.post("/jobs/{job_id}/cancel", response_model=JobRecord, dependencies=auth)
    async def cancel(job_id: str) -> JobRecord:
        return await service.cancel(job_id)

    @app.post("/jobs/{job_id}/flip-done", response_model=JobRecord, dependencies=auth)
    async def flip_done(job_id: str) -> JobRecord:
        return service.flip_done(job_id)

    @app.post("/jobs/{job_id}/align", dependencies=auth)
    async def align(job_id: str, body: AlignRequest) -> dict[str, Any]:
        return await service.align_mark(job_id, body.mark, body.jog)

    @app.get("/printer", dependencies=auth)
    async def printer(refresh: bool = False) -> dict[str, Any]:
        """Connection, firmware, temperatures, position; ``refresh=true`` asks the printer first."""
        return await service.printer_status(refresh)

    @app.post("/printer/emergency-stop", dependencies=auth)
    async def emergency_stop() -> dict[str, Any]:
        service.emergency_stop()
        return await service.printer_status()

    @app.post("/printer/recover", dependencies=auth)
    async def recover() -> dict[str, Any]:
        return await service.recover()

    @app.get("/events", dependencies=auth)
    async def events(request: Request) -> StreamingResponse:
        queue = service.bus.subscribe()

        async def stream() -> Any:
            try:
                yield ": ribbond events\n\n"
                while not await request.is_disconnected():
                    try:
                        event = await asyncio.wait_for(queue.get(), 15.0)
                    except asyncio.TimeoutError:
                        yield ": keep-alive\n\n"
                        continue
                    yield f"event: {event.get('type', 'message')}\ndata: {json.dumps(event, default=str)}\n\n"
            finally:
                service.bus.unsubscribe(queue)

        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache"})

    # the file may take the whole limit; its multipart framing and form fields get 64 kB more
    app.add_middleware(BodyLimit, limit=limit + 65536)
    return app
