"""The printer's camera (``service.camera``): whether there is one, its stream and a snapshot, fetched
by the daemon from ``[camera] stream_url`` / ``snapshot_url`` (why through the daemon:
``ribbond.daemon.components.camera``)."""

from __future__ import annotations

from fastapi import APIRouter, Response
from fastapi.responses import StreamingResponse

from ribbond.daemon.components.camera import BOUNDARY

from ..deps import Service
from ..errors import responses
from ..models import CameraView

router = APIRouter()

#: The stream's media type: one JPEG per part, each replacing the one before.
STREAM_TYPE = f"multipart/x-mixed-replace; boundary={BOUNDARY}"
#: No cache may keep a frame; a reverse proxy (nginx) must pass the parts on as they come.
LIVE = {"Cache-Control": "no-store", "X-Accel-Buffering": "no"}


@router.get("/camera", response_model=CameraView, responses=responses())
async def camera(service: Service) -> CameraView:
    return CameraView.model_validate(service.camera.view())


@router.get("/camera/stream", response_class=StreamingResponse, responses={
    **responses(404, 502), 200: {"description": "MJPEG: one JPEG per part, each with its Content-Length, "
                                               "until the client leaves or the camera stops",
                                 "content": {STREAM_TYPE: {"schema": {"type": "string"}}}}})
async def stream(service: Service) -> StreamingResponse:
    """The camera's frames as they come (the newest when the client is ready for one); 502 when the
    camera does not answer with a frame, 404 without a camera."""
    return StreamingResponse(await service.camera.open_stream(), media_type=STREAM_TYPE, headers=LIVE)


@router.get("/camera/snapshot", response_class=Response, responses={
    **responses(404, 502), 200: {"description": "one JPEG", "content": {"image/jpeg": {"schema": {"type": "string"}}}}})
async def snapshot(service: Service) -> Response:
    """One frame of the camera now (``snapshot_url``'s, else the stream's next)."""
    return Response(await service.camera.snapshot(), media_type="image/jpeg", headers=LIVE)
