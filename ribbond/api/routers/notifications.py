"""Notifications (``service.notifier``): what was sent to the operator's services and what failed,
and a test message."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter
from pydantic import BaseModel, Field

from ..deps import Service
from ..errors import responses

router = APIRouter()


class Delivery(BaseModel):
    """One notice to one service."""

    id: int = Field(description="the notice (one notice goes to every URL)")
    at: float = Field(description="unix time the delivery ended")
    event: str = Field(description="awaiting_flip, alignment, fresh_frame, done, failed, interrupted, halted "
                                   "or test")
    job_id: str | None
    title: str
    url: str = Field(description="the service, its secrets masked")
    status: Literal["sent", "failed", "timeout", "dropped"]
    error: str | None = Field(description="why it was not sent (the service's words, a timeout, a full queue)")
    duration_s: float | None


class Notifications(BaseModel):
    """The notifications: their setup, counts since the daemon started, the last deliveries."""

    enabled: bool = Field(description="[notify] urls are configured")
    urls: list[str] = Field(description="the services, their secrets masked")
    events: list[str]
    timeout_s: float
    sent: int = Field(ge=0)
    failed: int = Field(ge=0, description="deliveries failed, timed out or dropped")
    last_sent: Delivery | None
    last_failed: Delivery | None
    deliveries: list[Delivery] = Field(description="the last 50, newest first")


class SentTest(BaseModel):
    """A test message, queued for every service; its deliveries appear in GET /notifications."""

    id: int
    urls: list[str]


@router.get("/notifications", response_model=Notifications, responses=responses())
async def notifications(service: Service) -> Notifications:
    """What was sent to the operator's services, and what failed and why."""
    return Notifications.model_validate(service.notifier.view())


@router.post("/notifications/test", status_code=202, response_model=SentTest,
             responses=responses(409, mutating=True))
async def notifications_test(service: Service) -> SentTest:
    """Send a test message to every configured service (409: notifications are off)."""
    return SentTest.model_validate(service.notifier.test())
