"""Calibration plans: one ready two-sided job per sheet, and the plan's files
(``service.calibrations``)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.responses import FileResponse

from ..deps import Service, file_response
from ..errors import responses
from ..models import CalibrationFileName, CalibrationRequest, Ident
from ..openapi import file_content, links

router = APIRouter()

_CREATED = {201: {"links": {
    **links("cal_id=$response.body#/calibration", {"GetCalibrationFile": "calibration_file"}),
    **links("job_id=$response.body#/jobs/0", {"GetFirstJob": "job", "StartFirstJob": "start"})}}}


@router.post("/calibrations", status_code=201,
             responses={**responses(409, 503, mutating=True, body=True), **_CREATED})
async def calibrate(service: Service, body: CalibrationRequest) -> dict[str, Any]:
    """A calibration plan for this printer: one ready two-sided job per sheet (issue 15)."""
    spec = body.model_dump(exclude_none=True, exclude={"start"})
    return await service.calibrations.submit_calibration(spec, body.start)


@router.get("/calibrations/{cal_id}/files/{name}", response_class=FileResponse,
            responses={**responses(404, 422), **file_content([".json", ".csv", ".png", ".svg"])})
async def calibration_file(service: Service, cal_id: Ident, name: CalibrationFileName) -> FileResponse:
    return file_response(service.calibrations.calibration_file(cal_id, name))
