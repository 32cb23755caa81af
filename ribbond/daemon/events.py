"""The daemon's event bus: what the server-sent events (``GET /events``) carry to the dashboard and
``ribbonctl watch``. Components publish plain dicts with a ``type`` (job, progress, printer,
alignment, notice, deleted); the API only subscribes."""

from __future__ import annotations

import asyncio
import contextlib
from typing import Any


class EventBus:
    """Fan-out of events to live subscribers (server-sent events); a slow one loses old events."""

    def __init__(self) -> None:
        self._subscribers: set[asyncio.Queue[dict[str, Any]]] = set()

    def subscribe(self) -> asyncio.Queue[dict[str, Any]]:
        """A new subscriber's queue (at most 256 events waiting: the oldest are dropped)."""
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=256)
        self._subscribers.add(q)
        return q

    def unsubscribe(self, q: asyncio.Queue[dict[str, Any]]) -> None:
        self._subscribers.discard(q)

    def publish(self, event: dict[str, Any]) -> None:
        # never blocks the publisher (the print task): a full queue loses its oldest event
        for q in list(self._subscribers):
            if q.full():
                with contextlib.suppress(asyncio.QueueEmpty):
                    q.get_nowait()
            q.put_nowait(event)
