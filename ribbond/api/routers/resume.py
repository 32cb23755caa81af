"""Pause and resume a print, and the frame check before a resumed print (``service.resumer``)."""

from __future__ import annotations

from fastapi import APIRouter

from ..deps import Service, job_status
from ..errors import responses
from ..models import FrameOkRequest, Ident, JobStatus, ResumeRequest
from .jobs import JOB_ACTION

router = APIRouter()


@router.post("/jobs/{job_id}/pause", response_model=JobStatus, responses=JOB_ACTION)
async def pause(service: Service, job_id: Ident) -> JobStatus:
    return job_status(service, await service.resumer.pause(job_id))


@router.post("/jobs/{job_id}/resume", response_model=JobStatus,
             responses=responses(404, 409, 503, mutating=True, body=True))
async def resume(service: Service, job_id: Ident, body: ResumeRequest | None = None) -> JobStatus:
    return job_status(service, await service.resumer.resume(job_id, body.partial if body is not None else None))


@router.post("/jobs/{job_id}/frame-ok", response_model=JobStatus,
             responses=responses(404, 409, 503, mutating=True, body=True))
async def frame_ok(service: Service, job_id: Ident, body: FrameOkRequest | None = None) -> JobStatus:
    keep = body.keep_alignment if body is not None else False
    return job_status(service, await service.resumer.frame_ok(job_id, keep))
