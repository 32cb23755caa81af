"""The REST API: routes onto ``RibbonService`` methods, pydantic models in and out, no business logic.

OpenAPI at ``/docs`` (Swagger UI served from the package: it works on a host without internet).
Errors: a request the job's state does not allow is 409 with the state and the commands possible
now; an unknown job or file 404; bad input 422; an upload over the limit 413; the printer not
connected or halted 503. When a token is configured (always when listening beyond loopback), every
route but the documentation needs ``Authorization: Bearer <token>``, compared in constant time.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import tempfile
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import Depends, FastAPI, File, Form, HTTPException, Query, Request, Response, UploadFile
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, StreamingResponse
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field
from swagger_ui_bundle import swagger_ui_path

from .alignment import AlignmentRefused
from .config import tokens_match
from .jobs import IllegalTransition, JobState
from .printer.errors import LinkError
from .service import NotFound, RibbonService, ServiceError
from .store import JobRecord, Transition

#: Files of a job that can be fetched.
JOB_FILES = {"preview.png": "design", "preview.svg": "design", "design.json": "design",
             "front.gcode": "design", "back.gcode": "design", "combined.gcode": "design",
             "target.obj": "design", "flat.obj": "design", "deployed.obj": "design", "deployed.png": "design",
             "back-corrected.gcode": "job",
             "program.gcode": "job"}
_CHUNK = 1 << 20


class NextStep(BaseModel):
    """What the operator does next."""

    instruction: str
    commands: list[str] = Field(description="the exact commands possible now")


class JobStatus(JobRecord):
    """A job as the API shows it: the stored record, its progress and what to do next."""

    progress: float = Field(0.0, ge=0.0, le=1.0, description="0–1: of the compile while compiling, else of "
                                                              "the print (both sides)")
    compile_progress: float | None = Field(None, description="the stored progress within a compile stage")
    eta_s: float | None = Field(None, description="seconds left of the print (the programs' time estimate "
                                                  "scaled by the measured rate); 0 when done")
    elapsed_s: float | None = Field(None, description="seconds since this run started (while it runs)")
    ribbon: int | None = Field(None, description="the ribbon being printed, from 1")
    ribbons: int | None = Field(None, description="ribbons on the side being printed")
    print_side: str | None = Field(None, description="the side printed now or next")
    waits_for_operator: bool = Field(False, description="nothing happens until the operator acts")
    fit: dict[str, Any] | None = Field(None, description="in state fitted: the alignment's fit under review "
                                                         "(rotation_deg, offset, rms_mm, max_residual_mm)")
    next: NextStep


class JogRequest(BaseModel):
    dx: float = Field(description="mm")
    dy: float = Field(description="mm")
    dz: float = Field(0.0, description="mm")


class GotoRequest(BaseModel):
    x: float = Field(description="mm, machine coordinates")
    y: float = Field(description="mm, machine coordinates")


class GcodeRequest(BaseModel):
    commands: list[str] = Field(min_length=1, description="one G-code command or a short list")


class HeatRequest(BaseModel):
    nozzle: float | None = Field(None, description="°C; default the profile's print temperature")
    bed: float | None = Field(None, description="°C")


class CalibrationRequest(BaseModel):
    """``POST /calibrations``: the plan's grid and ribbons (``ribbond.calibration.spec``), all optional."""

    thicknesses: list[float] | None = None
    spacings: list[float] | None = None
    sides: list[str] | None = None
    ribbon_length: float | None = None
    ribbon_width: float | None = None
    mu1: float | None = None
    prestretch: float | None = None
    base_table: str | None = None
    fabric: str | None = None
    material: str | None = None
    min_coupon_width: float | None = None
    printer_profile: str | None = None
    start: bool = False


class TableRequest(BaseModel):
    toml: str = Field(description="the text of a curvature table's TOML file")


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


class ResumeRequest(BaseModel):
    """Resuming: for an interrupted print, what to do with the part begun and not proven printed."""

    partial: Literal["skip", "reprint"] | None = Field(None, description="skip it (default) or print it again")


class FrameOkRequest(BaseModel):
    """The frame of a resumed print is checked; for the back, whether the stored alignment holds."""

    keep_alignment: bool = Field(False, description="the frame was not moved: keep the stored correction")


class AlignRequest(BaseModel):
    """One registration mark: the head is on it (``here``), or the jog from where the head was sent
    to the mark (no jog: it was on the mark)."""

    mark: int | None = Field(None, description="the mark, numbered from 1 (design.json's "
                                                     "registration_marks[mark - 1]); default: the one the head was sent to")
    jog: tuple[float, float] | None = Field(None, description="(dx, dy) mm from where the head was sent to the mark")
    here: bool = Field(False, description="the nozzle is over the mark now (after jogging it there)")
    review: bool = Field(False, description="after the last mark, wait in 'fitted' for accept or re-seat "
                                            "instead of printing the back at once")


def create_app(service: RibbonService, token: str | None) -> FastAPI:
    """The FastAPI application over ``service``; ``token`` None means no authentication."""
    app = FastAPI(title="ribbond", version="1", description=__doc__, docs_url=None, redoc_url=None)
    limit = int(service.config.limits.max_upload_mb * 1024 * 1024)
    app.mount("/docs-assets", StaticFiles(directory=swagger_ui_path), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    async def docs() -> HTMLResponse:
        return get_swagger_ui_html(openapi_url=app.openapi_url or "/openapi.json", title="ribbond API",
                                   swagger_js_url="/docs-assets/swagger-ui-bundle.js",
                                   swagger_css_url="/docs-assets/swagger-ui.css",
                                   swagger_favicon_url="/docs-assets/favicon-32x32.png")

    def status(record: JobRecord) -> JobStatus:
        return JobStatus.model_validate(service.status(record))

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
                                                      "command": exc.command, "allowed": exc.allowed,
                                                      "allowed_states": exc.allowed_states})

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

    @app.post("/jobs", status_code=201, response_model=JobStatus, dependencies=auth)
    async def submit(mesh: Annotated[UploadFile | None, File(description="OBJ, PLY, STL or OFF: a design")] = None,
                     gcode: Annotated[UploadFile | None, File(description="a plain G-code program")] = None,
                     parameters: Annotated[str, Form(description="design parameters, JSON")] = "{}",
                     start: Annotated[bool, Form(description="print as soon as it is ready")] = False) -> JobStatus:
        if (mesh is None) == (gcode is None):
            raise ValueError("upload either a mesh (field 'mesh') or a G-code program (field 'gcode')")
        upload = mesh if mesh is not None else gcode
        assert upload is not None
        params: Any = {}
        if mesh is not None:
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
                while chunk := await upload.read(_CHUNK):
                    size += len(chunk)
                    if size > limit:
                        raise HTTPException(413, f"upload exceeds the limit of {limit} bytes (limits.max_upload_mb)")
                    out.write(chunk)
            if mesh is not None:
                return status(service.submit(tmp, mesh.filename or "mesh.obj", params, start))
            return status(await service.submit_gcode(tmp, upload.filename or "program.gcode", start))
        finally:
            tmp.unlink(missing_ok=True)

    @app.post("/calibrations", status_code=201, dependencies=auth)
    async def calibrate(body: CalibrationRequest) -> dict[str, Any]:
        """A calibration plan for this printer: one ready two-sided job per sheet (issue 15)."""
        spec = body.model_dump(exclude_none=True, exclude={"start"})
        return await service.submit_calibration(spec, body.start)

    @app.get("/calibrations/{cal_id}/files/{name}", dependencies=auth)
    async def calibration_file(cal_id: str, name: str) -> FileResponse:
        return FileResponse(service.calibration_file(cal_id, name))

    @app.get("/tables", dependencies=auth)
    async def tables() -> list[dict[str, Any]]:
        """The curvature tables a design may name: shipped ones and the daemon's own."""
        return service.tables()

    @app.get("/tables/{name}", dependencies=auth)
    async def table(name: str) -> dict[str, Any]:
        return service.table(name)

    @app.post("/tables", status_code=201, dependencies=auth)
    async def add_table(body: TableRequest) -> dict[str, Any]:
        """Add or replace a daemon table from the text of its TOML file (named by its ``name``)."""
        return service.add_table(body.toml)

    @app.delete("/tables/{name}", status_code=204, dependencies=auth)
    async def remove_table(name: str) -> Response:
        service.remove_table(name)
        return Response(status_code=204)

    @app.get("/jobs", response_model=list[JobStatus], dependencies=auth)
    async def jobs(response: Response,
                   state: Annotated[list[JobState] | None, Query(description="only jobs in these states")] = None,
                   limit: Annotated[int | None, Query(ge=0, le=1000, description="at most this many")] = None,
                   offset: Annotated[int, Query(ge=0, description="skip the newest this many")] = 0) -> list[JobStatus]:
        """Jobs, newest first; ``X-Total-Count`` is the number matching the filter."""
        response.headers["X-Total-Count"] = str(service.store.count(state))
        return [status(j) for j in service.jobs(state, limit, offset)]

    @app.get("/jobs/{job_id}", response_model=JobStatus, dependencies=auth)
    async def job(job_id: str) -> JobStatus:
        return status(service.job(job_id))

    @app.delete("/jobs/{job_id}", status_code=204, dependencies=auth)
    async def delete(job_id: str) -> Response:
        service.delete(job_id)
        return Response(status_code=204)

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

    @app.post("/jobs/{job_id}/start", response_model=JobStatus, dependencies=auth)
    async def start(job_id: str) -> JobStatus:
        return status(service.start_job(job_id))

    @app.post("/jobs/{job_id}/pause", response_model=JobStatus, dependencies=auth)
    async def pause(job_id: str) -> JobStatus:
        return status(await service.pause(job_id))

    @app.post("/jobs/{job_id}/resume", response_model=JobStatus, dependencies=auth)
    async def resume(job_id: str, body: ResumeRequest | None = None) -> JobStatus:
        return status(await service.resume(job_id, body.partial if body is not None else None))

    @app.post("/jobs/{job_id}/frame-ok", response_model=JobStatus, dependencies=auth)
    async def frame_ok(job_id: str, body: FrameOkRequest | None = None) -> JobStatus:
        return status(await service.frame_ok(job_id, body.keep_alignment if body is not None else False))

    @app.post("/jobs/{job_id}/cancel", response_model=JobStatus, dependencies=auth)
    async def cancel(job_id: str) -> JobStatus:
        return status(await service.cancel(job_id))

    @app.post("/jobs/{job_id}/flip-done", response_model=JobStatus, dependencies=auth)
    async def flip_done(job_id: str) -> JobStatus:
        return status(await service.flip_done(job_id))

    @app.post("/jobs/{job_id}/align", dependencies=auth)
    async def align(job_id: str, body: AlignRequest) -> dict[str, Any]:
        return await service.align_mark(job_id, body.mark, body.jog, body.here, body.review)

    @app.post("/jobs/{job_id}/accept", response_model=JobStatus, dependencies=auth)
    async def accept(job_id: str) -> JobStatus:
        return status(await service.accept_fit(job_id))

    @app.post("/jobs/{job_id}/re-seat", response_model=JobStatus, dependencies=auth)
    async def re_seat(job_id: str) -> JobStatus:
        return status(await service.re_seat(job_id))

    @app.post("/printer/home", dependencies=auth)
    async def home() -> dict[str, Any]:
        return await service.home()

    @app.post("/printer/jog", dependencies=auth)
    async def jog(body: JogRequest) -> dict[str, Any]:
        return await service.jog(body.dx, body.dy, body.dz)

    @app.post("/printer/goto", dependencies=auth)
    async def goto(body: GotoRequest) -> dict[str, Any]:
        return await service.goto(body.x, body.y)

    @app.post("/printer/gcode", dependencies=auth)
    async def gcode(body: GcodeRequest) -> dict[str, Any]:
        return await service.gcode(body.commands)

    @app.post("/printer/heat", dependencies=auth)
    async def heat(body: HeatRequest) -> dict[str, Any]:
        return await service.heat(body.nozzle, body.bed)

    @app.post("/printer/cool", dependencies=auth)
    async def cool() -> dict[str, Any]:
        return await service.cool()

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

    # The dashboard (issue 14): the page at / and its files under /ui. Static files hold no data,
    # so they need no token; the page asks for one when the API answers 401.
    web = Path(__file__).parent / "web"
    app.mount("/ui", StaticFiles(directory=web), name="ui")

    @app.get("/", include_in_schema=False)
    async def dashboard() -> FileResponse:
        return FileResponse(web / "index.html", headers={"Cache-Control": "no-cache"})

    # the file may take the whole limit; its multipart framing and form fields get 64 kB more
    app.add_middleware(BodyLimit, limit=limit + 65536)
    return app
