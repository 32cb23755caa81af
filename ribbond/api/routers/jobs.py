"""Jobs: upload (a mesh to compile, or a G-code program), list, show, delete, their transitions and
files, start, cancel, and a new prediction of a design (``RibbonService``, ``service.predictor``)."""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, HTTPException, Query, Response, UploadFile
from fastapi.responses import FileResponse

from ribbond.daemon.jobs import JobState
from ribbond.daemon.records import NotFound
from ribbond.daemon.store import Transition
from ribbond.design.params import parameters_from_json

from ..deps import FormBool, Service, file_response, form_fields, job_status
from ..errors import responses
from ..models import JOB_FILES, Ident, JobFile, JobStatus, PredictRequest, ShapeDeviation
from ..openapi import file_content, links

router = APIRouter()

_CHUNK = 1 << 20
#: The operations on a job, linked from its creation: link name -> operationId.
JOB_LINKS = {"GetJob": "job", "GetTransitions": "transitions", "GetJobFile": "job_file", "StartJob": "start",
             "PauseJob": "pause", "ResumeJob": "resume", "CancelJob": "cancel", "FlipDone": "flip_done",
             "AlignJob": "align", "AcceptFit": "accept", "ReSeat": "re_seat", "FrameOk": "frame_ok",
             "DeleteJob": "delete", "PredictJob": "predict"}
#: Every action on a job answers these.
JOB_ACTION = responses(404, 409, 422, 503, mutating=True)


def parse_parameters(text: str, mesh: bool, gcode: bool, same_frame: bool) -> dict[str, Any]:
    """The form's ``parameters`` as a JSON object, and the form's fields consistent with each other."""
    if mesh == gcode:
        raise ValueError("upload either a mesh (field 'mesh') or a G-code program (field 'gcode')")
    params = parameters_from_json(text, program=gcode)
    if mesh and same_frame:
        raise ValueError("same_frame: only a plain G-code program may print on the frame as it is; "
                         "a design always needs a fresh stretched frame")
    return params


async def spool(upload: UploadFile, out: Any, limit: int) -> None:
    """Copy the upload into ``out`` by chunks: 413 as soon as it passes ``limit`` bytes."""
    size = 0
    while chunk := await upload.read(_CHUNK):
        size += len(chunk)
        if size > limit:
            raise HTTPException(413, f"upload exceeds the limit of {limit} bytes (limits.max_upload_mb)")
        out.write(chunk)


@contextlib.asynccontextmanager
async def spooled(service: Any, upload: UploadFile) -> AsyncIterator[Path]:
    """The upload in a file of the state's ``uploads/`` (within ``limits.max_upload_mb``), removed
    afterwards: the service moves what it keeps."""
    uploads = Path(service.config.state_dir) / "uploads"
    uploads.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(dir=uploads, prefix="upload-")
    tmp = Path(tmp_name)
    try:
        with open(fd, "wb") as out:
            await spool(upload, out, int(service.config.limits.max_upload_mb * 1024 * 1024))
        yield tmp
    finally:
        tmp.unlink(missing_ok=True)


@router.post("/jobs", status_code=201, response_model=JobStatus,
             dependencies=[form_fields("mesh", "gcode", "parameters", "start", "same_frame",
                                       booleans=("start", "same_frame"))],
             responses={**responses(409, mutating=True, body=True),
                        201: {"links": links("job_id=$response.body#/id", JOB_LINKS)}})
async def submit(service: Service,
                 mesh: Annotated[UploadFile | None, File(description="OBJ, PLY, STL or OFF: a design")] = None,
                 gcode: Annotated[UploadFile | None, File(description="a plain G-code program")] = None,
                 parameters: Annotated[str, Form(description="design parameters, JSON")] = "{}",
                 start: Annotated[FormBool, Form(description="print as soon as it is ready")] = "false",
                 same_frame: Annotated[FormBool, Form(description="a G-code program that prints on the frame as "
                                                      "it is: no fresh frame is asked for before it")] = "false",
                 ) -> JobStatus:
    """Upload a mesh (a design is compiled from it) or a G-code program (checked against the profile).
    A mesh is read and validated at once, as the compile's intake reads it: a file the engine cannot
    use is refused (422 naming the problem and its line) and nothing is kept."""
    now, same = start == "true", same_frame == "true"
    params = parse_parameters(parameters, mesh is not None, gcode is not None, same)
    upload = mesh if mesh is not None else gcode
    assert upload is not None
    async with spooled(service, upload) as tmp:
        if mesh is not None:
            return job_status(service, await service.submit(tmp, mesh.filename or "mesh.obj", params, now))
        return job_status(service, await service.submit_gcode(tmp, upload.filename or "program.gcode", now, same))


@router.get("/jobs", response_model=list[JobStatus], responses=responses(422))
async def jobs(service: Service, response: Response,
               state: Annotated[list[JobState] | None, Query(description="only jobs in these states")] = None,
               limit: Annotated[int | None, Query(ge=0, le=1000, description="at most this many")] = None,
               offset: Annotated[int, Query(ge=0, le=2**31 - 1, description="skip the newest this many")] = 0,
               ) -> list[JobStatus]:
    """Jobs, newest first; ``X-Total-Count`` is the number matching the filter."""
    response.headers["X-Total-Count"] = str(service.store.count(state))
    return [job_status(service, j) for j in service.jobs(state, limit, offset)]


@router.get("/jobs/{job_id}", response_model=JobStatus, responses=responses(404, 422))
async def job(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, service.job(job_id))


@router.delete("/jobs/{job_id}", status_code=204, response_class=Response,
               responses=responses(404, 409, 422, mutating=True))
async def delete(service: Service, job_id: Ident) -> Response:
    service.delete(job_id)
    return Response(status_code=204)


@router.get("/jobs/{job_id}/transitions", response_model=list[Transition], responses=responses(404, 422))
async def transitions(service: Service, job_id: Ident) -> list[Transition]:
    service.job(job_id)
    return service.store.transitions(job_id)


@router.get("/jobs/{job_id}/files/{name}", response_class=FileResponse,
            responses={**responses(404, 422), **file_content([".png", ".jpg", ".svg", ".json", ".gcode", ".obj"])})
async def job_file(service: Service, job_id: Ident, name: JobFile) -> FileResponse:
    record = service.job(job_id)
    where = JOB_FILES[name.value]
    base = Path(record.design_dir) if where == "design" and record.design_dir else service.job_dir(job_id)
    path = base / name.value
    if not path.is_file():
        raise NotFound(f"job {job_id} has no {name.value} (yet)")
    return file_response(path)


@router.get("/jobs/{job_id}/deviation", response_model=ShapeDeviation, responses=responses(404, 422))
async def deviation(service: Service, job_id: Ident) -> ShapeDeviation:
    """The distance of each vertex of the predicted shape to the target (the dashboard's 3D view)."""
    return ShapeDeviation.model_validate(await service.shapes.deviation(service.job(job_id)))


@router.post("/jobs/{job_id}/start", response_model=JobStatus, responses=JOB_ACTION)
async def start(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, service.start_job(job_id))


@router.post("/jobs/{job_id}/predict", status_code=202, response_model=JobStatus,
             responses=responses(404, 409, 422, mutating=True, body=True))
async def predict(service: Service, job_id: Ident, body: PredictRequest | None = None) -> JobStatus:
    """Predict the design's deployed shape again as its folder is, with another table: replaces deployed.obj, deployed.png and report.deployed; the job's
    ``prediction`` follows it (events as the compile's)."""
    body = body or PredictRequest()
    service.predictor.start(job_id, body.table)
    return job_status(service, service.job(job_id))


@router.post("/jobs/{job_id}/cancel", response_model=JobStatus, responses=JOB_ACTION)
async def cancel(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, await service.cancel(job_id))
