"""The event stream: the bus's events as server-sent events (``service.bus``)."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator

from fastapi import APIRouter, Request
from fastapi.responses import StreamingResponse

from ..deps import Service
from ..errors import responses
from ..openapi import EVENT

router = APIRouter()

#: Seconds without an event before a keep-alive comment.
KEEP_ALIVE_S = 15.0


@router.get("/events", response_class=StreamingResponse, responses={
    **responses(), 200: {"description": "server-sent events, a keep-alive comment every 15 s",
                         "content": {"text/event-stream": {"schema": EVENT}}}})
async def events(service: Service, request: Request) -> StreamingResponse:
    queue = service.bus.subscribe()

    async def stream() -> AsyncIterator[str]:
        try:
            yield ": ribbond events\n\n"
            while not await request.is_disconnected():
                try:
                    event = await asyncio.wait_for(queue.get(), KEEP_ALIVE_S)
                except asyncio.TimeoutError:
                    yield ": keep-alive\n\n"
                    continue
                yield f"event: {event.get('type', 'message')}\ndata: {json.dumps(event, default=str)}\n\n"
        finally:
            service.bus.unsubscribe(queue)

    return StreamingResponse(stream(), media_type="text/event-stream", headers={"Cache-Control": "no-cache"})
