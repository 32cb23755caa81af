"""The pages a browser opens, outside the document: the API's documentation (Swagger UI, its files
served from the package under ``/docs-assets``: it works without internet) and the dashboard's page
(its files under ``/ui``), and the site's icon at ``/favicon.ico`` (the dashboard's SVG: a browser asks
for it on any page). ``create_app`` mounts both directories."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse

#: The dashboard (issue 14): its page and the files it loads.
WEB = Path(__file__).parents[2] / "web"

router = APIRouter()


@router.get("/docs", include_in_schema=False)
async def docs(request: Request) -> HTMLResponse:
    return get_swagger_ui_html(openapi_url=request.app.openapi_url or "/openapi.json", title="ribbond API",
                               swagger_js_url="/docs-assets/swagger-ui-bundle.js",
                               swagger_css_url="/docs-assets/swagger-ui.css",
                               swagger_favicon_url="/docs-assets/favicon-32x32.png")


@router.get("/", include_in_schema=False)
async def dashboard() -> FileResponse:
    return FileResponse(WEB / "index.html", headers={"Cache-Control": "no-cache"})


@router.get("/favicon.ico", include_in_schema=False)
async def favicon() -> FileResponse:
    return FileResponse(WEB / "favicon.svg", media_type="image/svg+xml", headers={"Cache-Control": "max-age=86400"})
