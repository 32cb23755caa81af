"""What every router takes from the application: the service (``app.state.service``, set by
``create_app``), a job's status as the API shows it, and a file as a response."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from fastapi import Depends, Request
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
