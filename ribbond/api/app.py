"""The REST API: routes onto ``RibbonService`` and its components (``service.manual``,
``service.aligner``, ``service.resumer``, ``service.library``, ``service.calibrations``), pydantic
models in and out, no business logic.

OpenAPI at ``/docs`` (Swagger UI served from the package: it works on a host without internet); it
documents every status a route answers with its body model (``ribbond.api.errors``) and links the
operations of one job, table or calibration (``POST /jobs`` -> ``GET /jobs/{job_id}`` ...).
Errors: a request the job's state (or the printer's: halted) does not allow is 409 with the state
and the commands possible now; an unknown job or file 404; bad input 422; an upload over the limit
413; the printer not connected 503. In front of every route, before any body is read,
``ribbond.api.guard`` checks the Host header (421), the origin of state-changing requests (403) and,
when a token is configured (``api.token`` or ``api.token_file``, on any address; always beyond
loopback), ``Authorization: Bearer <token>`` (401) on every path but the documentation and the
dashboard's files.
"""

from __future__ import annotations

import asyncio
import json
import tempfile
from pathlib import Path
from enum import Enum
from typing import Annotated, Any, Literal

from fastapi import FastAPI, File, Form, HTTPException, Path as PathParam, Query, Request, Response, UploadFile
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse, StreamingResponse
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field
from swagger_ui_bundle import swagger_ui_path

from ribbond.daemon.components.manual import MAX_MANUAL_COMMANDS
from ribbond.daemon.jobs import JobState
from ribbond.daemon.records import NotFound
from ribbond.daemon.service import RibbonService
from ribbond.daemon.store import JobRecord, Transition
from ribbond.design.params import DesignParameters
from ribbond.design.thickness import TABLE_DIR
from . import errors
from .errors import responses
from .guard import Guard, HostRule, Policy

#: Files of a job that can be fetched.
JOB_FILES = {"preview.png": "design", "preview.svg": "design", "design.json": "design",
             "front.gcode": "design", "back.gcode": "design", "combined.gcode": "design",
             "target.obj": "design", "flat.obj": "design", "deployed.obj": "design", "deployed.png": "design",
             "back-corrected.gcode": "job",
             "program.gcode": "job"}
#: The media type of each kind of file served (named, so the OpenAPI document can list them).
MEDIA_TYPES = {".png": "image/png", ".svg": "image/svg+xml", ".json": "application/json",
               ".gcode": "text/x.gcode", ".obj": "model/obj", ".csv": "text/csv"}
_CHUNK = 1 << 20
#: A job file's name in a path: one of ``JOB_FILES`` (the document lists them).
JobFile = Enum("JobFile", {name: name for name in JOB_FILES}, type=str)  # type: ignore[misc]
#: A calibration's files (``Calibrations.calibration_file``).
CalibrationFileName = Annotated[str, PathParam(pattern=r"^(plan\.json|coupons\.csv|sheet-[0-9]{1,3}\.(png|svg))$")]
#: Ids and names in paths: longer ones cannot exist (job ids are 12 hex digits, table names at most
#: 64 characters), and are refused without being echoed.
Ident = Annotated[str, PathParam(max_length=64)]


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
    alignment: dict[str, Any] | None = Field(None, description="in state aligning: the registration marks "
                                               "(marks), those measured and kept (kept) and those to measure "
                                               "again after a refused fit or a re-seat (remeasure), from 1")
    verdict: list[str] | None = Field(None, description="a design's verdict, one sentence per line: the "
                                                        "stretch bounds, clamped thicknesses, ribbons dropped "
                                                        "or trimmed, the prediction (ribbond.design.verdict)")
    prediction: dict[str, Any] | None = Field(
        None, description="the design's last prediction asked for (POST /jobs/{id}/predict) in this daemon's "
        "life: state (running, done, failed), fraction 0–1, message, table, fine; when done the new "
        "report.deployed (deployed) and verdict; when failed the error")
    next: NextStep


class PredictRequest(BaseModel):
    """``POST /jobs/{id}/predict``: the prediction's curvature table and model."""

    table: str | None = Field(None, min_length=1, max_length=64,
                              description="a curvature table's name (GET /tables); default the design's")
    fine: bool = Field(False, description="the ribbon-resolved model (minutes) instead of the homogenized one")


class JogRequest(BaseModel):
    dx: float = Field(description="mm")
    dy: float = Field(description="mm")
    dz: float = Field(0.0, description="mm")


class GotoRequest(BaseModel):
    x: float = Field(description="mm, machine coordinates")
    y: float = Field(description="mm, machine coordinates")


class GcodeRequest(BaseModel):
    commands: list[Annotated[str, Field(pattern=r"\S")]] = Field(
        min_length=1, max_length=MAX_MANUAL_COMMANDS, description="one G-code command or a short list")


class HeatRequest(BaseModel):
    # the upper bounds are the profile's: written into the document by _refine_openapi
    nozzle: float | None = Field(None, ge=0, description="°C; default the profile's print temperature")
    bed: float | None = Field(None, ge=0, description="°C")


class CalibrationRequest(BaseModel):
    """``POST /calibrations``: the plan's grid and ribbons (``ribbond.calibration.spec``), all optional."""

    # the spec's own bounds, so the document states them; its cross-field rules (increasing grids,
    # mu1 > ribbon_length) are the spec's to check (422)
    # at most 16 of each: one request's plan stays bounded (16 x 16 x 2 coupons)
    thicknesses: list[Annotated[float, Field(gt=0)]] | None = Field(None, min_length=2, max_length=16,
                                                                     description="mm, increasing")
    spacings: list[Annotated[float, Field(gt=0)]] | None = Field(None, min_length=2, max_length=16,
                                                                  description="mm, increasing")
    sides: list[Literal["front", "back"]] | None = Field(None, min_length=1, max_length=2)
    ribbon_length: float | None = Field(None, gt=0)
    ribbon_width: float | None = Field(None, gt=0)
    mu1: float | None = Field(None, gt=0)
    prestretch: float | None = Field(None, gt=1.0)
    base_table: str | None = Field(None, min_length=1, max_length=64)
    fabric: str | None = None
    material: str | None = None
    min_coupon_width: float | None = Field(None, gt=0)
    printer_profile: str | None = Field(None, min_length=1)
    start: bool = False


def _example_table() -> str:
    """The shipped table's TOML as a daemon table named ``example``: the document's example body."""
    text = (TABLE_DIR / "tpu95a-lycra-default.toml").read_text(encoding="utf-8")
    return text.replace('name = "tpu95a-lycra-default"', 'name = "example"', 1)


class TableRequest(BaseModel):
    toml: str = Field(description="the text of a curvature table's TOML file", examples=[_example_table()])


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


def _links(target: str, operations: dict[str, str]) -> dict[str, Any]:
    """OpenAPI links from a created resource to the operations on it (``operations``: link name ->
    operationId), the path parameter taken from the response (``target``: ``param=$response...``)."""
    param, expression = target.split("=", 1)
    return {name: {"operationId": op, "parameters": {param: expression}} for name, op in operations.items()}


_JOB_LINKS = {"GetJob": "job", "GetTransitions": "transitions", "GetJobFile": "job_file", "StartJob": "start",
              "PauseJob": "pause", "ResumeJob": "resume", "CancelJob": "cancel", "FlipDone": "flip_done",
              "AlignJob": "align", "AcceptFit": "accept", "ReSeat": "re_seat", "FrameOk": "frame_ok",
              "DeleteJob": "delete", "PredictJob": "predict"}


#: One server-sent event: its type (``job``, ``printer``, ...) and its JSON data.
_EVENT = {"type": "object", "required": ["data"],
          "properties": {"event": {"type": "string"}, "data": {"type": "string", "description": "JSON"}}}


def _file_content(suffixes: list[str]) -> dict[int | str, dict[str, Any]]:
    def schema(suffix: str) -> dict[str, Any]:
        return {"type": "object"} if suffix == ".json" else {"type": "string"}
    return {200: {"description": "the file", "content": {MEDIA_TYPES[s]: {"schema": schema(s)} for s in suffixes}}}


def _file(path: Path) -> FileResponse:
    return FileResponse(path, media_type=MEDIA_TYPES.get(path.suffix.lower(), "application/octet-stream"))


def create_app(service: RibbonService, token: str | None) -> FastAPI:
    """The FastAPI application over ``service``; ``token`` None means no authentication."""
    app = FastAPI(title="ribbond", version="1", description=__doc__, docs_url=None, redoc_url=None,
                  generate_unique_id_function=lambda route: route.name)
    limit = int(service.config.limits.max_upload_mb * 1024 * 1024)
    app.mount("/docs-assets", StaticFiles(directory=swagger_ui_path), name="docs-assets")
    errors.install(app)

    @app.get("/docs", include_in_schema=False)
    async def docs() -> HTMLResponse:
        return get_swagger_ui_html(openapi_url=app.openapi_url or "/openapi.json", title="ribbond API",
                                   swagger_js_url="/docs-assets/swagger-ui-bundle.js",
                                   swagger_css_url="/docs-assets/swagger-ui.css",
                                   swagger_favicon_url="/docs-assets/favicon-32x32.png")

    def status(record: JobRecord) -> JobStatus:
        return JobStatus.model_validate(service.status(record))

    job_created = {201: {"links": _links("job_id=$response.body#/id", _JOB_LINKS)}}

    @app.post("/jobs", status_code=201, response_model=JobStatus,
              responses={**responses(409, mutating=True, body=True), **job_created})
    async def submit(mesh: Annotated[UploadFile | None, File(description="OBJ, PLY, STL or OFF: a design")] = None,
                     gcode: Annotated[UploadFile | None, File(description="a plain G-code program")] = None,
                     parameters: Annotated[str, Form(description="design parameters, JSON")] = "{}",
                     start: Annotated[bool, Form(description="print as soon as it is ready")] = False,
                     same_frame: Annotated[bool, Form(description="a G-code program that prints on the frame as it "
                                                      "is: no fresh frame is asked for before it")] = False,
                     ) -> JobStatus:
        """Upload a mesh (a design is compiled from it) or a G-code program (checked against the profile)."""
        if (mesh is None) == (gcode is None):
            raise ValueError("upload either a mesh (field 'mesh') or a G-code program (field 'gcode')")
        upload = mesh if mesh is not None else gcode
        assert upload is not None
        try:
            params: Any = json.loads(parameters)
        except ValueError as exc:
            raise ValueError(f"parameters: not valid JSON: {exc}") from None
        if not isinstance(params, dict):
            raise ValueError("parameters: expected a JSON object")
        if gcode is not None and params:           # said, not silently dropped
            raise ValueError("parameters: a G-code program takes no design parameters (they are a mesh's)")
        if mesh is not None and same_frame:
            raise ValueError("same_frame: only a plain G-code program may print on the frame as it is; "
                             "a design always needs a fresh stretched frame")
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
            return status(await service.submit_gcode(tmp, upload.filename or "program.gcode", start, same_frame))
        finally:
            tmp.unlink(missing_ok=True)

    cal_links = {201: {"links": {
        **_links("cal_id=$response.body#/calibration", {"GetCalibrationFile": "calibration_file"}),
        **_links("job_id=$response.body#/jobs/0", {"GetFirstJob": "job", "StartFirstJob": "start"})}}}

    @app.post("/calibrations", status_code=201,
              responses={**responses(409, 503, mutating=True, body=True), **cal_links})
    async def calibrate(body: CalibrationRequest) -> dict[str, Any]:
        """A calibration plan for this printer: one ready two-sided job per sheet (issue 15)."""
        spec = body.model_dump(exclude_none=True, exclude={"start"})
        return await service.calibrations.submit_calibration(spec, body.start)

    @app.get("/calibrations/{cal_id}/files/{name}", response_class=FileResponse,
             responses={**responses(404, 422), **_file_content([".json", ".csv", ".png", ".svg"])})
    async def calibration_file(cal_id: Ident, name: CalibrationFileName) -> FileResponse:
        return _file(service.calibrations.calibration_file(cal_id, name))

    @app.get("/tables", responses=responses())
    async def tables() -> list[dict[str, Any]]:
        """The curvature tables a design may name: shipped ones and the daemon's own."""
        return service.library.tables()

    @app.get("/tables/{name}", responses=responses(404, 422))
    async def table(name: Ident) -> dict[str, Any]:
        return service.library.table(name)

    table_links = {201: {"links": _links("name=$response.body#/name", {"GetTable": "table",
                                                                        "RemoveTable": "remove_table"})}}

    @app.post("/tables", status_code=201, responses={**responses(409, mutating=True, body=True), **table_links})
    async def add_table(body: TableRequest) -> dict[str, Any]:
        """Add or replace a daemon table from the text of its TOML file (named by its ``name``)."""
        return service.library.add_table(body.toml)

    @app.delete("/tables/{name}", status_code=204, response_class=Response,
                responses=responses(404, 409, 422, mutating=True))
    async def remove_table(name: Ident) -> Response:
        service.library.remove_table(name)
        return Response(status_code=204)

    @app.get("/jobs", response_model=list[JobStatus], responses=responses(422))
    async def jobs(response: Response,
                   state: Annotated[list[JobState] | None, Query(description="only jobs in these states")] = None,
                   limit: Annotated[int | None, Query(ge=0, le=1000, description="at most this many")] = None,
                   offset: Annotated[int, Query(ge=0, le=2**31 - 1, description="skip the newest this many")] = 0) -> list[JobStatus]:
        """Jobs, newest first; ``X-Total-Count`` is the number matching the filter."""
        response.headers["X-Total-Count"] = str(service.store.count(state))
        return [status(j) for j in service.jobs(state, limit, offset)]

    @app.get("/jobs/{job_id}", response_model=JobStatus, responses=responses(404, 422))
    async def job(job_id: Ident) -> JobStatus:
        return status(service.job(job_id))

    @app.delete("/jobs/{job_id}", status_code=204, response_class=Response,
                responses=responses(404, 409, 422, mutating=True))
    async def delete(job_id: Ident) -> Response:
        service.delete(job_id)
        return Response(status_code=204)

    @app.get("/jobs/{job_id}/transitions", response_model=list[Transition], responses=responses(404, 422))
    async def transitions(job_id: Ident) -> list[Transition]:
        service.job(job_id)
        return service.store.transitions(job_id)

    @app.get("/jobs/{job_id}/files/{name}", response_class=FileResponse,
             responses={**responses(404, 422), **_file_content([".png", ".svg", ".json", ".gcode", ".obj"])})
    async def job_file(job_id: Ident, name: JobFile) -> FileResponse:
        record = service.job(job_id)
        where = JOB_FILES[name.value]
        base = Path(record.design_dir) if where == "design" and record.design_dir else service.job_dir(job_id)
        path = base / name.value
        if not path.is_file():
            raise NotFound(f"job {job_id} has no {name.value} (yet)")
        return _file(path)

    job_action = responses(404, 409, 422, 503, mutating=True)

    @app.post("/jobs/{job_id}/start", response_model=JobStatus, responses=job_action)
    async def start(job_id: Ident) -> JobStatus:
        return status(service.start_job(job_id))

    @app.post("/jobs/{job_id}/pause", response_model=JobStatus, responses=job_action)
    async def pause(job_id: Ident) -> JobStatus:
        return status(await service.resumer.pause(job_id))

    @app.post("/jobs/{job_id}/resume", response_model=JobStatus,
              responses=responses(404, 409, 503, mutating=True, body=True))
    async def resume(job_id: Ident, body: ResumeRequest | None = None) -> JobStatus:
        return status(await service.resumer.resume(job_id, body.partial if body is not None else None))

    @app.post("/jobs/{job_id}/predict", status_code=202, response_model=JobStatus,
              responses=responses(404, 409, 422, mutating=True, body=True))
    async def predict(job_id: Ident, body: PredictRequest | None = None) -> JobStatus:
        """Predict the design's deployed shape again as its folder is, with another table or the
        ribbon-resolved model: replaces deployed.obj, deployed.png and report.deployed; the job's
        ``prediction`` follows it (events as the compile's)."""
        body = body or PredictRequest()
        service.predictor.start(job_id, body.table, body.fine)
        return status(service.job(job_id))

    @app.post("/jobs/{job_id}/frame-ok", response_model=JobStatus,
              responses=responses(404, 409, 503, mutating=True, body=True))
    async def frame_ok(job_id: Ident, body: FrameOkRequest | None = None) -> JobStatus:
        return status(await service.resumer.frame_ok(job_id, body.keep_alignment if body is not None else False))

    @app.post("/jobs/{job_id}/cancel", response_model=JobStatus, responses=job_action)
    async def cancel(job_id: Ident) -> JobStatus:
        return status(await service.cancel(job_id))

    @app.post("/jobs/{job_id}/flip-done", response_model=JobStatus, responses=job_action)
    async def flip_done(job_id: Ident) -> JobStatus:
        return status(await service.aligner.flip_done(job_id))

    @app.post("/jobs/{job_id}/align", responses=responses(404, 409, 503, mutating=True, body=True))
    async def align(job_id: Ident, body: AlignRequest) -> dict[str, Any]:
        return await service.aligner.align_mark(job_id, body.mark, body.jog, body.here, body.review)

    @app.post("/jobs/{job_id}/accept", response_model=JobStatus, responses=job_action)
    async def accept(job_id: Ident) -> JobStatus:
        return status(await service.aligner.accept_fit(job_id))

    @app.post("/jobs/{job_id}/re-seat", response_model=JobStatus, responses=job_action)
    async def re_seat(job_id: Ident) -> JobStatus:
        return status(await service.aligner.re_seat(job_id))

    printer_action = responses(409, 422, 503, mutating=True)
    printer_body = responses(409, 503, mutating=True, body=True)

    @app.post("/printer/home", responses=printer_action)
    async def home() -> dict[str, Any]:
        return await service.manual.home()

    @app.post("/printer/jog", responses=printer_body)
    async def jog(body: JogRequest) -> dict[str, Any]:
        return await service.manual.jog(body.dx, body.dy, body.dz)

    @app.post("/printer/goto", responses=printer_body)
    async def goto(body: GotoRequest) -> dict[str, Any]:
        return await service.manual.goto(body.x, body.y)

    @app.post("/printer/gcode", responses=printer_body)
    async def gcode(body: GcodeRequest) -> dict[str, Any]:
        """Typed G-code, checked whole as a plain G-code job is (inside the frame, above the fabric,
        temperatures within the profile; feed rates clamped, said in ``notes``) before any of it is
        sent: 422 names the command and the limit. ``answers``: per command, the printer's lines
        (``sent``: the command as sent, when clamped). Unchecked with ``[manual] raw_console = true``."""
        return await service.manual.gcode(body.commands)

    @app.post("/printer/heat", responses=printer_body)
    async def heat(body: HeatRequest) -> dict[str, Any]:
        return await service.manual.heat(body.nozzle, body.bed)

    @app.post("/printer/cool", responses=printer_action)
    async def cool() -> dict[str, Any]:
        return await service.manual.cool()

    @app.get("/printer", responses=responses(422, 503))
    async def printer(refresh: bool = False) -> dict[str, Any]:
        """Connection, firmware, temperatures, position, the frame (fresh or used); ``refresh=true``
        asks the printer first."""
        return {**await service.manual.printer_status(refresh), "frame": service.frame.status()}

    @app.post("/printer/frame-ready", responses=responses(409, mutating=True))
    async def frame_ready() -> dict[str, Any]:
        """A fresh stretched frame is loaded: the job waiting for one goes on (409 while a job holds
        the printer)."""
        return service.frame.ready()

    @app.get("/printer/temperatures", responses=responses())
    async def temperatures() -> dict[str, Any]:
        """The nozzle's and bed's temperatures and targets of the last 30 minutes, oldest first
        (``samples``: ``t`` unix s, ``T``/``Tt`` nozzle, ``B``/``Bt`` bed, °C; at most one per ``interval_s``)."""
        return service.temperatures.as_json()

    @app.post("/printer/emergency-stop", responses=printer_action)
    async def emergency_stop() -> dict[str, Any]:
        service.manual.emergency_stop()
        return await service.manual.printer_status()

    @app.post("/printer/recover", responses=printer_action)
    async def recover() -> dict[str, Any]:
        return await service.manual.recover()

    @app.get("/events", response_class=StreamingResponse, responses={
        **responses(), 200: {"description": "server-sent events, a keep-alive comment every 15 s",
                             "content": {"text/event-stream": {"schema": _EVENT}}}})
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
    web = Path(__file__).parents[1] / "web"
    app.mount("/ui", StaticFiles(directory=web), name="ui")

    @app.get("/", include_in_schema=False)
    async def dashboard() -> FileResponse:
        return FileResponse(web / "index.html", headers={"Cache-Control": "no-cache"})

    _refine_openapi(app, token is not None, service)
    api = service.config.api
    # the file may take the whole limit; its multipart framing and form fields get 64 kB more
    app.add_middleware(Guard, policy=Policy(token, HostRule(api.host, tuple(api.allowed_hosts)), limit + 65536))
    return app


def _refine_openapi(app: FastAPI, bearer: bool, service: RibbonService) -> None:
    """What FastAPI's generated document cannot say: the upload is one of ``mesh`` and ``gcode``,
    each named with its suffix, ``parameters`` a JSON ``DesignParameters`` object; the profile's
    bounds of ``heat`` and ``goto`` (the service checks them); and, with a token, the bearer scheme
    on every operation (the gate enforces it)."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = build()
            components = schema.setdefault("components", {})
            _describe_upload(schema, components.setdefault("schemas", {}))
            _profile_bounds(components["schemas"], service)
            if bearer:
                components["securitySchemes"] = {"bearer": {"type": "http", "scheme": "bearer",
                                                            "description": "the daemon's API token"}}
                for ops in schema["paths"].values():
                    for op in ops.values():
                        op["security"] = [{"bearer": []}]
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def _profile_bounds(components: dict[str, Any], service: RibbonService) -> None:
    t, (x0, y0, x1, y1) = service.profile.temperatures, service.profile.frame.bounds

    def bound(model: str, field: str, low: float, high: float) -> None:
        prop = components[model]["properties"][field]
        number = next((s for s in prop.get("anyOf", []) if s.get("type") == "number"), prop)
        number.update({"minimum": low, "maximum": high})

    bound("HeatRequest", "nozzle", 0, t.nozzle_max)
    bound("HeatRequest", "bed", 0, t.bed_max)
    bound("GotoRequest", "x", x0, x1)
    bound("GotoRequest", "y", y0, y1)


def _describe_upload(schema: dict[str, Any], components: dict[str, Any]) -> None:
    params = DesignParameters.model_json_schema(ref_template="#/components/schemas/{model}")
    components.update(params.pop("$defs", {}))
    components["DesignParameters"] = params
    body = components["Body_submit"]
    props = body["properties"]
    for field in ("mesh", "gcode"):
        props[field] = next(s for s in props[field]["anyOf"] if s.get("type") == "string") | {
            "description": props[field]["description"]}
    props["parameters"] = {"$ref": "#/components/schemas/DesignParameters",
                           "description": "design parameters (a JSON object; with a mesh only)"}
    body["oneOf"] = [{"required": ["mesh"], "not": {"required": ["gcode"]}},
                     {"required": ["gcode"], "not": {"required": ["mesh"]},
                      "properties": {"parameters": {"maxProperties": 0}}}]
    content = schema["paths"]["/jobs"]["post"]["requestBody"]["content"]["multipart/form-data"]
    content["encoding"] = {
        "parameters": {"contentType": "application/json"},
        **{field: {"headers": {"Content-Disposition": {"schema": {
            "type": "string", "example": f'form-data; name="{field}"; filename="{name}"'}}}}
           for field, name in (("mesh", "mesh.obj"), ("gcode", "program.gcode"))}}
