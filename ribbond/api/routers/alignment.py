"""The flip and the alignment of the back over the registration marks (``service.aligner``)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from ..deps import Service, job_status
from ..errors import responses
from ..models import AlignRequest, Ident, JobStatus
from .jobs import JOB_ACTION

router = APIRouter()


@router.post("/jobs/{job_id}/flip-done", response_model=JobStatus, responses=JOB_ACTION)
async def flip_done(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, await service.aligner.flip_done(job_id))


@router.post("/jobs/{job_id}/align", responses=responses(404, 409, 503, mutating=True, body=True))
async def align(service: Service, job_id: Ident, body: AlignRequest) -> dict[str, Any]:
    return await service.aligner.align_mark(job_id, body.mark, body.jog, body.here, body.review)


@router.post("/jobs/{job_id}/accept", response_model=JobStatus, responses=JOB_ACTION)
async def accept(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, await service.aligner.accept_fit(job_id))


@router.post("/jobs/{job_id}/re-seat", response_model=JobStatus, responses=JOB_ACTION)
async def re_seat(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, await service.aligner.re_seat(job_id))
