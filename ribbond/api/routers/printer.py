"""The printer as the operator sees it: its status with the frame's, the fresh frame loaded
(``service.frame``), and the temperatures of the last 30 minutes (``service.temperatures``)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from ..deps import Service
from ..errors import responses

router = APIRouter()


@router.get("/printer", responses=responses(422, 503))
async def printer(service: Service, refresh: bool = False) -> dict[str, Any]:
    """Connection, firmware, temperatures, position, the frame (fresh or used); ``refresh=true``
    asks the printer first."""
    return {**await service.manual.printer_status(refresh), "frame": service.frame.status()}


@router.post("/printer/frame-ready", responses=responses(409, mutating=True))
async def frame_ready(service: Service) -> dict[str, Any]:
    """A fresh stretched frame is loaded: the job waiting for one goes on (409 while a job holds
    the printer)."""
    return service.frame.ready()


@router.get("/printer/temperatures", responses=responses())
async def temperatures(service: Service) -> dict[str, Any]:
    """The nozzle's and bed's temperatures and targets of the last 30 minutes, oldest first
    (``samples``: ``t`` unix s, ``T``/``Tt`` nozzle, ``B``/``Bt`` bed, °C; at most one per ``interval_s``)."""
    return service.temperatures.as_json()
