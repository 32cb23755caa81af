"""Curvature tables: the shipped ones and the daemon's own (``service.library``)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response

from ..deps import Service
from ..errors import responses
from ..models import Ident, TableRequest
from ..openapi import links

router = APIRouter()

_CREATED = {201: {"links": links("name=$response.body#/name", {"GetTable": "table", "RemoveTable": "remove_table"})}}


@router.get("/tables", responses=responses())
async def tables(service: Service) -> list[dict[str, Any]]:
    """The curvature tables a design may name: shipped ones and the daemon's own."""
    return service.library.tables()


@router.get("/tables/{name}", responses=responses(404, 422))
async def table(service: Service, name: Ident) -> dict[str, Any]:
    return service.library.table(name)


@router.post("/tables", status_code=201, responses={**responses(409, mutating=True, body=True), **_CREATED})
async def add_table(service: Service, body: TableRequest) -> dict[str, Any]:
    """Add or replace a daemon table from the text of its TOML file (named by its ``name``)."""
    return service.library.add_table(body.toml)


@router.delete("/tables/{name}", status_code=204, response_class=Response,
               responses=responses(404, 409, 422, mutating=True))
async def remove_table(service: Service, name: Ident) -> Response:
    service.library.remove_table(name)
    return Response(status_code=204)
