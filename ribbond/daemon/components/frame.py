"""The frame on the printer and the gate between jobs (issue 22).

Every job here prints on a fresh, pre-stretched frame: printing on the fabric a job before left
(printed, maybe released) spoils both. The daemon knows the frame on the printer: ``fresh`` (the
operator confirmed a fresh stretched frame, ``frame-ready``, and nothing has printed on it since) or
``used`` (a job reached printing on it since; also at the first start: nothing was confirmed). It is
kept in the store, so a restarted daemon knows it.

Before the print task heats for a job that needs a fresh frame (every design and calibration job,
a plain G-code program unless submitted with ``same_frame``) while the frame is ``used``, the job
waits: ``ready``, its stage ``WAIT_STAGE``, the heaters off and the head where it is, until the
operator confirms a fresh frame (or cancels the job). A resumed interrupted job prints on its own
frame and is checked by ``frame-ok`` instead: the gate does not apply to it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from ..jobs import JobState, state_name
from ..records import JobRecords, ServiceError
from ..store import FRAME_FRESH, FRAME_USED, JobRecord
from .heaters import Heaters
from .run import PrintState

log = logging.getLogger(__name__)

#: The stage of a ready job waiting at the gate (what a person reads in ``status``).
WAIT_STAGE = "waiting for a fresh frame"
#: What the operator does then.
INSTRUCTION = "load a fresh stretched frame, then confirm: ribbonctl frame-ready"


def needs_fresh_frame(job: JobRecord) -> bool:
    """Every design (and calibration) job; a plain G-code program unless it said ``same_frame``."""
    return job.kind != "gcode" or not job.same_frame


def waits_at_gate(job: JobRecord) -> bool:
    """The job is queued and waits for the operator to confirm a fresh frame."""
    return job.state is JobState.READY and job.start_when_ready and job.stage == WAIT_STAGE


class FrameGate:
    """The frame's state (in the store) and the wait for a fresh one."""

    def __init__(self, records: JobRecords, state: PrintState, heaters: Heaters) -> None:
        self.records, self.state, self.heaters = records, state, heaters
        self._confirmed = asyncio.Event()            # set by frame-ready: the waiting job looks again

    def status(self) -> dict[str, Any]:
        """``state`` (fresh, used), ``since`` (unix time), ``job_id`` (the job that used it, if any),
        ``waiting_job`` (the job waiting for a fresh frame, if any)."""
        frame = self.records.store.frame()
        waiting = next((j.id for j in self.records.store.active() if waits_at_gate(j)), None)
        return {**frame, "waiting_job": waiting}

    def _publish(self) -> None:
        self.records.bus.publish({"type": "frame", "frame": self.status()})

    def used(self, job_id: str) -> None:
        """A job reached printing on the frame (either side, a resumed print too)."""
        if self.records.store.frame()["state"] != FRAME_USED:
            self.records.store.set_frame(FRAME_USED, job_id)
            log.info("the frame is used (job %s printed on it)", job_id)
            self._publish()

    def ready(self) -> dict[str, Any]:
        """The operator loaded a fresh stretched frame: record it; a job waiting for it goes on.
        Refused (``ServiceError``) while a job holds the printer: the frame under it is not fresh."""
        holding = [j for j in self.records.store.active() if j.state.holds_printer]
        if self.state.run is not None or holding:
            job = holding[0] if holding else self.records.get(self.state.run.job_id)  # type: ignore[union-attr]
            raise ServiceError(f"cannot confirm a fresh frame: job {job.id} is {state_name(job.state, job.kind)} on the printer "
                               "(the frame under a running job is not fresh); confirm it once that job has "
                               f"ended (ribbonctl cancel {job.id} ends it now)")
        self.records.store.set_frame(FRAME_FRESH, None)
        log.info("the operator confirmed a fresh frame")
        for job in self.records.store.active():
            if waits_at_gate(job):                   # it goes on now: its answer and status say so
                self.records.publish(self.records.store.update(job.id, stage="a fresh frame is loaded"))
        self._confirmed.set()
        self._publish()
        return self.status()

    async def wait_fresh(self, job_id: str) -> JobRecord | None:
        """In the print task, before heating for ``job_id``: once the frame is fresh, the job (its
        stage cleared); None if it is no longer to print (cancelled, deleted, the daemon stops).
        Meanwhile the job waits ``ready`` with ``WAIT_STAGE``, the heaters off, the head left alone."""
        records, store = self.records, self.records.store
        log.info("job %s waits for a fresh frame (ribbonctl frame-ready)", job_id)
        records.publish(store.update(job_id, stage=WAIT_STAGE))
        self._publish()
        await self.heaters.off_if_on()                # a program may have left them on: not over the fabric
        while store.frame()["state"] != FRAME_FRESH and not self.state.stopping and self._still_queued(job_id):
            self._confirmed.clear()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._confirmed.wait(), 0.2)   # (a cancel is seen within 0.2 s)
        if not self._still_queued(job_id) or self.state.stopping:
            return None
        job = store.update(job_id, stage=None)
        records.publish(job)
        self._publish()
        return job

    def _still_queued(self, job_id: str) -> bool:
        if not self.records.exists(job_id):
            return False
        job = self.records.get(job_id)
        return job.state is JobState.READY and job.start_when_ready
