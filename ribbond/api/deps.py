"""What every router takes from the application: the service (``app.state.service``, set by
``create_app``), a job's status as the API shows it, a file as a response, a multipart form's
fields checked as a JSON body's are, and a form's boolean as the document states it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import Depends, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse

from ribbond.daemon.service import RibbonService
from ribbond.daemon.store import JobRecord

from .models import MEDIA_TYPES, JobStatus


def get_service(request: Request) -> RibbonService:
    """The service the application was created over."""
    service: RibbonService = request.app.state.service
    return service


#: A route's parameter for the service: ``service: Service``.
Service = Annotated[RibbonService, Depends(get_service)]


def job_status(service: RibbonService, record: JobRecord) -> JobStatus:
    """A job as the API shows it: the record, its progress and what to do next."""
    return JobStatus.model_validate(service.status(record))


def file_response(path: Path) -> FileResponse:
    """A file with the media type its suffix names."""
    return FileResponse(path, media_type=MEDIA_TYPES.get(path.suffix.lower(), "application/octet-stream"))


#: A multipart form's boolean: the text ``true`` or ``false``, as the document's enum says (a form
#: has no booleans; "1", "on" or "yes" are refused, not guessed).
FormBool = Literal["true", "false"]


def form_fields(*names: str, booleans: tuple[str, ...] = ()) -> Any:
    """A route's dependency: its multipart form carries only ``names``; any other field is refused
    with 422 naming it, as ``extra="forbid"`` refuses a JSON body's. A field of ``booleans`` sent
    must be ``true`` or ``false`` (FastAPI reads an empty one as absent: refused here too, as the
    document's enum says). The form is parsed once: Starlette keeps it on the request."""
    async def check(request: Request) -> None:
        form = await request.form()
        errors = [{"type": "extra_forbidden", "loc": ("body", name),
                   "msg": f"not a field of this form (its fields: {', '.join(names)})"}
                  for name in sorted(set(form.keys()) - set(names))]
        errors += [{"type": "literal_error", "loc": ("body", name), "msg": "Input should be 'true' or 'false'"}
                   for name in booleans if name in form and form.get(name) not in ("true", "false")]
        if errors:
            raise RequestValidationError(errors)
    return Depends(check)
