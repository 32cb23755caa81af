"""The part of OctoPrint's API that slicers' "send to printer" uses (issue 27;
``service.octoprint``): ``/api/version``, ``/api/server``, ``/api/settings`` (Cura's plugin checks
the key with it), ``/api/files/local`` (the upload), ``/api/job``, ``/api/printer``, in OctoPrint's
shapes. The token is the daemon's, sent as ``X-Api-Key`` (the gate takes it on every path); the
gate checks it, the Host and the Origin before the body is read, as on every route. Statuses are
OctoPrint's: a file that is neither G-code nor a mesh is 415, one that cannot be made a job 400,
the printer not operational (``/api/printer``) 409.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Request, Response, UploadFile

from ribbond.daemon.components.octoprint import SETTINGS, VERSION

from ..deps import Service
from ..errors import responses
from ..models import (OctoPrintJob, OctoPrintPrinter, OctoPrintServer, OctoPrintSettings, OctoPrintUpload,
                      OctoPrintVersion)
from .jobs import spooled

router = APIRouter()


def _upload_responses() -> dict[int | str, dict[str, Any]]:
    out = responses(409, 415, mutating=True, body=True)
    out[400] = {**out[400], "description": "the file cannot be made a job (empty, a mesh the engine cannot "
                                           "use, a program the profile refuses, userdata that are not design "
                                           "parameters), or the body cannot be parsed"}
    out[409] = {**out[409], "description": "limits.max_jobs jobs are already queued or printing"}
    out[201] = {"description": "the file is a job", "headers": {
        "Location": {"schema": {"type": "string"}, "description": "the job (GET /jobs/{job_id})"}}}
    return out


@router.get("/api/version", response_model=OctoPrintVersion, responses=responses())
async def octoprint_version() -> dict[str, str]:
    """What slicers check first: ``text`` starts with ``OctoPrint``."""
    return VERSION


@router.get("/api/server", response_model=OctoPrintServer, responses=responses())
async def octoprint_server() -> dict[str, Any]:
    return {"version": VERSION["server"], "safemode": False}


@router.get("/api/settings", response_model=OctoPrintSettings, responses=responses())
async def octoprint_settings() -> dict[str, Any]:
    """The part of OctoPrint's settings clients read: no SD card, no camera, no plugins."""
    return SETTINGS


@router.post("/api/files/local", status_code=201, response_model=OctoPrintUpload, responses=_upload_responses())
async def octoprint_upload(
        service: Service, request: Request, response: Response,
        file: Annotated[UploadFile, File(description="a G-code program (.gcode, .gco, .g, .nc): a plain G-code "
                                                     "job; a mesh (.obj, .stl, .ply, .off): a design job")],
        print_: Annotated[bool, Form(alias="print", description="queue it to print (it waits for a fresh "
                                                                "frame as every job)")] = False,
        select: Annotated[bool, Form(description="keep it ready to start (every upload is)")] = False,
        path: Annotated[str, Form(description="accepted as slicers send it; ribbond keeps no folders")] = "",
        userdata: Annotated[str, Form(description="a mesh's design parameters, JSON (as POST /jobs takes them)")] = "",
) -> dict[str, Any]:
    """Upload a slicer's file: it becomes a job, started when ``print`` is true."""
    async with spooled(service, file) as tmp:
        made = await service.octoprint.upload(tmp, file.filename or "", start=print_, select=select,
                                              userdata=userdata)
    job_url = str(request.url_for("job", job_id=made["job_id"]))
    refs = {"resource": job_url}
    if made["done"]:
        refs["download"] = str(request.url_for("job_file", job_id=made["job_id"], name="program.gcode"))
    response.headers["Location"] = job_url
    entry = {"name": made["name"], "display": made["name"], "path": made["name"], "origin": "local", "refs": refs}
    return {"files": {"local": entry}, **{k: made[k] for k in ("done", "effectiveSelect", "effectivePrint",
                                                                 "job_id")}}


@router.get("/api/job", response_model=OctoPrintJob, responses=responses())
async def octoprint_job(service: Service) -> dict[str, Any]:
    """The job on the printer, else the next queued to print, else the newest; its progress."""
    return service.octoprint.job()


@router.get("/api/printer", response_model=OctoPrintPrinter, responses=responses(409))
async def octoprint_printer(service: Service) -> dict[str, Any]:
    """Temperatures and state flags; 409 while the printer is not operational."""
    return await service.octoprint.printer()
