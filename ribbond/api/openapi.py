"""The OpenAPI document: what the routes say of themselves, and what FastAPI cannot generate.

The routers use ``links`` (from a created resource to the operations on it), ``file_content`` (the
media types of a file route) and ``EVENT`` (one server-sent event); ``refine`` adds, once, the
upload's alternatives, the profile's bounds and the bearer scheme.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI

from ribbond.daemon.service import RibbonService
from ribbond.design.params import DesignParameters

from .models import MEDIA_TYPES

#: One server-sent event: its type (``job``, ``printer``, ...) and its JSON data.
EVENT = {"type": "object", "required": ["data"],
         "properties": {"event": {"type": "string"}, "data": {"type": "string", "description": "JSON"}}}


#: The token, either way the gate takes it: a bearer token, or OctoPrint's X-Api-Key header.
SECURITY = {"bearer": {"type": "http", "scheme": "bearer", "description": "the daemon's API token"},
            "apiKey": {"type": "apiKey", "in": "header", "name": "X-Api-Key",
                       "description": "the daemon's API token, as OctoPrint's clients (slicers) send it"}}


def links(target: str, operations: dict[str, str]) -> dict[str, Any]:
    """OpenAPI links from a created resource to the operations on it (``operations``: link name ->
    operationId), the path parameter taken from the response (``target``: ``param=$response...``)."""
    param, expression = target.split("=", 1)
    return {name: {"operationId": op, "parameters": {param: expression}} for name, op in operations.items()}


def file_content(suffixes: list[str]) -> dict[int | str, dict[str, Any]]:
    """The 200 response of a file route: one media type per suffix it serves."""
    def schema(suffix: str) -> dict[str, Any]:
        return {"type": "object"} if suffix == ".json" else {"type": "string"}
    return {200: {"description": "the file", "content": {MEDIA_TYPES[s]: {"schema": schema(s)} for s in suffixes}}}


def refine(app: FastAPI, bearer: bool, service: RibbonService) -> None:
    """What FastAPI's generated document cannot say: the upload is one of ``mesh`` and ``gcode``,
    each named with its suffix, ``parameters`` a JSON ``DesignParameters`` object; the profile's
    bounds of ``heat`` and ``goto`` (the service checks them); and, with a token, its two schemes
    (a bearer token or ``X-Api-Key``) on every operation (the gate enforces them)."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = build()
            components = schema.setdefault("components", {})
            _describe_upload(schema, components.setdefault("schemas", {}))
            _profile_bounds(components["schemas"], service)
            if bearer:
                components["securitySchemes"] = SECURITY
                for ops in schema["paths"].values():
                    for op in ops.values():
                        op["security"] = [{"bearer": []}, {"apiKey": []}]
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


def _profile_bounds(components: dict[str, Any], service: RibbonService) -> None:
    t, (x0, y0, x1, y1) = service.profile.temperatures, service.profile.frame.bounds

    def bound(model: str, field: str, low: float, high: float) -> None:
        prop = components[model]["properties"][field]
        number = next((s for s in prop.get("anyOf", []) if s.get("type") == "number"), prop)
        number.update({"minimum": low, "maximum": high})

    bound("HeatRequest", "nozzle", 0, t.nozzle_max)
    bound("HeatRequest", "bed", 0, t.bed_max)
    adjust, body = service.profile.adjust, components["AdjustRequest"]["properties"]
    for field, (low, high) in (("speed", adjust.speed_percent), ("flow", adjust.flow_percent),
                               ("nozzle", (0, t.nozzle_max)), ("bed", (0, t.bed_max))):
        bound("AdjustRequest", field, low, high)
        number = next(s for s in body[field]["anyOf"] if s.get("type") == "number")
        body[field] = {**number, "description": body[field].get("description", "")}   # a number when given
    bound("GotoRequest", "x", x0, x1)
    bound("GotoRequest", "y", y0, y1)
    profile = components["CalibrationRequest"]["properties"]["printer_profile"]
    text = next((s for s in profile.get("anyOf", []) if s.get("type") == "string"), profile)
    text["enum"] = [service.config.printer_profile]             # the one printer this daemon drives


def _describe_upload(schema: dict[str, Any], components: dict[str, Any]) -> None:
    params = DesignParameters.model_json_schema(ref_template="#/components/schemas/{model}")
    components.update(params.pop("$defs", {}))
    components["DesignParameters"] = params
    body = components["Body_submit"]
    props = body["properties"]
    for field in ("mesh", "gcode"):                            # an empty file is refused (422)
        props[field] = next(s for s in props[field]["anyOf"] if s.get("type") == "string") | {
            "description": props[field]["description"], "minLength": 1}
    props["parameters"] = {"$ref": "#/components/schemas/DesignParameters",
                           "description": "design parameters (a JSON object; with a mesh only)"}
    body["oneOf"] = [{"required": ["mesh"], "not": {"required": ["gcode"]}},
                     {"required": ["gcode"], "not": {"required": ["mesh"]},
                      "properties": {"parameters": {"maxProperties": 0}}}]
    for form in ("Body_submit", "Body_submit_project"):           # deps.form_fields refuses any other
        components[form]["additionalProperties"] = False
    project = components["Body_submit_project"]["properties"]
    project["parameters"] = dict(props["parameters"])
    project["mesh"] = {**project["mesh"], "minLength": 1}
    schema["paths"]["/projects"]["post"]["requestBody"]["content"]["multipart/form-data"]["encoding"] = {
        "parameters": {"contentType": "application/json"},
        "mesh": {"headers": {"Content-Disposition": {"schema": {
            "type": "string", "example": 'form-data; name="mesh"; filename="mesh.obj"'}}}}}
    content = schema["paths"]["/jobs"]["post"]["requestBody"]["content"]["multipart/form-data"]
    content["encoding"] = {
        "parameters": {"contentType": "application/json"},
        **{field: {"headers": {"Content-Disposition": {"schema": {
            "type": "string", "example": f'form-data; name="{field}"; filename="{name}"'}}}}
           for field, name in (("mesh", "mesh.obj"), ("gcode", "program.gcode"))}}
