"""Projects: a mesh printed in panels, compiled once, one two-sided job per panel
(``service.submit_project``, ``service.projects``)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, File, Form, Query, UploadFile
from fastapi.responses import FileResponse

from ..deps import FormBool, Service, file_response, form_fields
from ..errors import responses
from ..models import Ident, ProjectFile, ProjectStatus
from ..openapi import file_content, links
from .jobs import parse_parameters, spooled

router = APIRouter()

#: The operations on a project, linked from its creation: link name -> operationId.
PROJECT_LINKS = {"GetProject": "project", "StartProject": "start_project", "CancelProject": "cancel_project",
                 "GetProjectFile": "project_file"}
#: The panels field: documented as the pattern the service checks (with a message naming the field).
PANELS = "^(auto|[2-9]|1[0-6])$"


@router.post("/projects", status_code=201, response_model=ProjectStatus,
             dependencies=[form_fields("mesh", "parameters", "panels", "seam_allowance", "start",
                                       booleans=("start",))],
             responses={**responses(409, mutating=True, body=True),
                        201: {"links": links("project_id=$response.body#/id", PROJECT_LINKS)}})
async def submit_project(service: Service,
                         mesh: Annotated[UploadFile, File(description="OBJ, PLY, STL or OFF: the target")],
                         parameters: Annotated[str, Form(description="design parameters, JSON")] = "{}",
                         panels: Annotated[str, Form(description="'auto' or the number of panels, 2 to 16",
                                                     json_schema_extra={"pattern": PANELS})] = "auto",
                         seam_allowance: Annotated[float, Form(ge=0.0, le=30.0, description="fabric left around "
                                                               "each panel for its seams, mm")] = 6.0,
                         start: Annotated[FormBool, Form(description="print the panels, in order, once "
                                                         "compiled")] = "false",
                         ) -> ProjectStatus:
    """Upload a mesh to print in panels: compiled once, then one two-sided job per panel. The mesh is
    read and validated at once, as a job's is (422 naming the problem; nothing kept)."""
    params = parse_parameters(parameters, True, False, False)
    async with spooled(service, mesh) as tmp:
        project = await service.submit_project(tmp, mesh.filename or "mesh.obj", params, panels, seam_allowance,
                                               start == "true")
    return ProjectStatus.model_validate(project)


@router.get("/projects", response_model=list[ProjectStatus], responses=responses(422))
async def projects(service: Service,
                   limit: Annotated[int | None, Query(ge=0, le=1000, description="at most this many")] = None,
                   ) -> list[ProjectStatus]:
    """Projects, newest first."""
    return [ProjectStatus.model_validate(p) for p in service.projects.list(limit)]


@router.get("/projects/{project_id}", response_model=ProjectStatus, responses=responses(404, 422))
async def project(service: Service, project_id: Ident) -> ProjectStatus:
    return ProjectStatus.model_validate(service.projects.show(project_id))


@router.post("/projects/{project_id}/start", response_model=ProjectStatus,
             responses=responses(404, 409, 422, mutating=True))
async def start_project(service: Service, project_id: Ident) -> ProjectStatus:
    """Print the panels not printed yet, in order."""
    return ProjectStatus.model_validate(service.projects.show(service.projects.start(project_id).id))


@router.post("/projects/{project_id}/cancel", response_model=ProjectStatus,
             responses=responses(404, 409, 422, mutating=True))
async def cancel_project(service: Service, project_id: Ident) -> ProjectStatus:
    """Cancel what is left: the compile, or every panel not printed (the one on the printer as a
    job's cancel: heaters off, head up)."""
    return ProjectStatus.model_validate(service.projects.show((await service.projects.cancel(project_id)).id))


@router.get("/projects/{project_id}/files/{name}", response_class=FileResponse,
            responses={**responses(404, 422), **file_content([".json", ".png", ".obj"])})
async def project_file(service: Service, project_id: Ident, name: ProjectFile) -> FileResponse:
    return file_response(service.projects.file(project_id, name.value))
