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
loopback), ``Authorization: Bearer <token>`` or ``X-Api-Key: <token>`` (401) on every path but the
documentation and the dashboard's files. Slicers send jobs through the part of OctoPrint's API they
use (``/api/...``, ``routers.octoprint``).
"""

from __future__ import annotations

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles
from swagger_ui_bundle import swagger_ui_path

from ribbond.daemon.service import RibbonService

from . import errors, openapi
from .guard import Guard, HostRule, Policy
from .routers import (alignment, calibrations, camera, events, jobs, manual, notifications, octoprint, pages, printer,
                      projects, resume, tables)

#: The routers in the order their paths appear in the document.
ROUTERS = (jobs, projects, resume, alignment, calibrations, tables, manual, printer, camera, notifications, events,
           octoprint, pages)


def create_app(service: RibbonService, token: str | None) -> FastAPI:
    """The FastAPI application over ``service``; ``token`` None means no authentication."""
    app = FastAPI(title="ribbond", version="1", description=__doc__, docs_url=None, redoc_url=None,
                  generate_unique_id_function=lambda route: route.name)
    app.state.service = service
    app.mount("/docs-assets", StaticFiles(directory=swagger_ui_path), name="docs-assets")
    # The dashboard's files hold no data, so they need no token; the page asks for one when the
    # API answers 401.
    app.mount("/ui", StaticFiles(directory=pages.WEB), name="ui")
    errors.install(app)
    for module in ROUTERS:
        app.include_router(module.router)
    openapi.refine(app, token is not None, service)
    api = service.config.api
    limit = int(service.config.limits.max_upload_mb * 1024 * 1024)
    # the file may take the whole limit; its multipart framing and form fields get 64 kB more
    app.add_middleware(Guard, policy=Policy(token, HostRule(api.host, tuple(api.allowed_hosts)), limit + 65536))
    return app
