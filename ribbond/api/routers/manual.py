"""Manual control of the printer: home, jog, goto, typed G-code, heat, cool, the emergency stop and
the recovery from it (``service.manual``); never while a program streams, but for the adjustments
(``/printer/adjust``; typed G-code and heat limited to them then)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from ..deps import Service
from ..errors import responses
from ..models import AdjustRequest, GcodeRequest, GotoRequest, HeatRequest, JogRequest

router = APIRouter()

PRINTER_ACTION = responses(409, 422, 503, mutating=True)
PRINTER_BODY = responses(409, 503, mutating=True, body=True)


@router.post("/printer/home", responses=PRINTER_ACTION)
async def home(service: Service) -> dict[str, Any]:
    return await service.manual.home()


@router.post("/printer/jog", responses=PRINTER_BODY)
async def jog(service: Service, body: JogRequest) -> dict[str, Any]:
    return await service.manual.jog(body.dx, body.dy, body.dz)


@router.post("/printer/goto", responses=PRINTER_BODY)
async def goto(service: Service, body: GotoRequest) -> dict[str, Any]:
    return await service.manual.goto(body.x, body.y)


@router.post("/printer/gcode", responses=PRINTER_BODY)
async def gcode(service: Service, body: GcodeRequest) -> dict[str, Any]:
    """Typed G-code, checked whole as a plain G-code job is (inside the frame, above the fabric,
    temperatures within the profile; feed rates clamped, said in ``notes``) before any of it is
    sent: 422 names the command and the limit. ``answers``: per command, the printer's lines
    (``sent``: the command as sent, when clamped). Unchecked with ``[manual] raw_console = true``.
    While a job's program streams, only M220, M221, M104, M140 (within the profile's limits), M105
    and M114 are accepted, sent beside the program (``printing``: the job's id); anything else 422."""
    return await service.manual.gcode(body.commands)


@router.post("/printer/adjust", responses=PRINTER_BODY)
async def adjust(service: Service, body: AdjustRequest) -> dict[str, Any]:
    """Adjust a print in progress (or the printer between prints): the feed override (M220), the
    flow (M221), the nozzle's and the bed's targets, sent as typed G-code is (the same check);
    ``printer``: the status after it, with ``speed_percent`` / ``flow_percent`` as the printer
    reports them."""
    return await service.manual.adjust(body.speed, body.flow, body.nozzle, body.bed)


@router.post("/printer/heat", responses=PRINTER_BODY)
async def heat(service: Service, body: HeatRequest) -> dict[str, Any]:
    return await service.manual.heat(body.nozzle, body.bed)


@router.post("/printer/cool", responses=PRINTER_ACTION)
async def cool(service: Service) -> dict[str, Any]:
    return await service.manual.cool()


@router.post("/printer/emergency-stop", responses=PRINTER_ACTION)
async def emergency_stop(service: Service) -> dict[str, Any]:
    service.manual.emergency_stop()
    return await service.manual.printer_status()


@router.post("/printer/recover", responses=PRINTER_ACTION)
async def recover(service: Service) -> dict[str, Any]:
    return await service.manual.recover()
