"""Calibration plans: asked for (made in the planner's process after the answer, as a compile is),
their state, one ready two-sided job per sheet once made, and the plan's files
(``service.calibrations``)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.responses import FileResponse

from ..deps import Service, file_response
from ..errors import responses
from ..models import CalibrationFileName, CalibrationRequest, CalibrationStatus, Ident
from ..openapi import file_content, links

router = APIRouter()

_LINKS = links("cal_id=$response.body#/calibration", {"GetCalibration": "calibration",
                                                       "GetCalibrationFile": "calibration_file"})


@router.post("/calibrations", status_code=202, response_model=CalibrationStatus,
             responses={**responses(409, 503, mutating=True, body=True), 202: {"links": _LINKS}})
async def calibrate(service: Service, body: CalibrationRequest) -> dict[str, Any]:
    """A calibration plan for this printer (issue 15): the request is checked and answered at once
    (``planning``); the plan is made in its own process, then one ready two-sided job per sheet
    (``GET /calibrations/{cal_id}``)."""
    spec = body.model_dump(exclude_none=True, exclude={"start"})
    return await service.calibrations.submit_calibration(spec, body.start)


@router.get("/calibrations/{cal_id}", response_model=CalibrationStatus, responses=responses(404, 422))
async def calibration(service: Service, cal_id: Ident) -> dict[str, Any]:
    """Where the plan stands: planning, ready (its sheets' jobs) or failed (why)."""
    return service.calibrations.calibration(cal_id)


@router.get("/calibrations/{cal_id}/files/{name}", response_class=FileResponse,
            responses={**responses(404, 422), **file_content([".json", ".csv", ".png", ".svg"])})
async def calibration_file(service: Service, cal_id: Ident, name: CalibrationFileName) -> FileResponse:
    return file_response(service.calibrations.calibration_file(cal_id, name))
