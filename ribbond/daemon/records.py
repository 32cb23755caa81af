"""The job records as the daemon's components share them: read from the store, changed through its
transitions (committed before they are published on the event bus), and the service's errors.

Every component that changes a job goes through ``JobRecords``, so no change reaches the event bus
(the dashboard, ``ribbonctl watch``) before the store has it: what is shown is what a restart finds.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .events import EventBus
from .jobs import JobState
from .store import JobRecord, JobStore, ProjectRecord

log = logging.getLogger(__name__)


class ServiceError(Exception):
    """A request that cannot be done now, with the reason (the API answers 409)."""


class NotFound(ServiceError):
    """No such job or file (the API answers 404)."""


class JobRecords:
    """The store's jobs with their events. ``describe`` is how a job is shown in its events (the
    service's ``status``: it needs the print run, which this class does not know)."""

    def __init__(self, store: JobStore, bus: EventBus, jobs_dir: Path, max_jobs: int,
                 describe: Callable[[JobRecord], dict[str, Any]]) -> None:
        self.store, self.bus, self.jobs_dir, self.max_jobs = store, bus, jobs_dir, max_jobs
        self._describe = describe

    def get(self, job_id: str) -> JobRecord:
        """The job, or ``NotFound``."""
        try:
            return self.store.get(job_id)
        except KeyError:
            raise NotFound(f"no job {job_id!r}") from None

    def project(self, project_id: str) -> ProjectRecord:
        """The project, or ``NotFound``."""
        try:
            return self.store.project(project_id)
        except KeyError:
            raise NotFound(f"no project {project_id!r}") from None

    def exists(self, job_id: str) -> bool:
        try:
            self.store.get(job_id)
        except KeyError:
            return False
        return True

    def dir(self, job_id: str) -> Path:
        """The job's own folder (upload, plans, the corrected back)."""
        return self.jobs_dir / job_id

    def publish(self, job: JobRecord, **extra: Any) -> None:
        self.bus.publish({"type": "job", "job": self._describe(job), **extra})

    def transition(self, job_id: str, new: JobState, **fields: Any) -> JobRecord:
        """Change the job's state (``jobs.TRANSITIONS``) and ``fields``; committed, then published."""
        job = self.store.transition(job_id, new, **fields)     # committed before it is published
        log.info("job %s -> %s%s", job_id, new.value, f" ({fields['reason']})" if fields.get("reason") else "")
        self.publish(job)
        return job

    async def wait_state(self, job_id: str, done: Callable[[JobState], bool], timeout: float) -> JobRecord:
        """The job once ``done(state)`` holds (or after ``timeout`` s, as it is then)."""
        deadline = time.monotonic() + timeout
        while True:
            job = self.get(job_id)
            if done(job.state) or time.monotonic() > deadline:
                return job
            await asyncio.sleep(0.02)

    def queued(self) -> int:
        """Jobs that count against ``limits.max_jobs``: compiling or waiting to, printing or queued
        to print (a ``ready`` design nobody started does not count)."""
        return sum(1 for j in self.store.active() if j.state is not JobState.READY or j.start_when_ready)

    def check_queue(self) -> None:
        """Refuse (``ServiceError``) one more job to compile or print beyond ``limits.max_jobs``."""
        if self.queued() >= self.max_jobs:
            raise ServiceError(f"{self.max_jobs} jobs are already queued or printing "
                               "(limits.max_jobs); wait for some to finish, or cancel some")


def has_program(job: JobRecord) -> bool:
    """The job has a program to print (a compiled design's front, or a checked G-code program)."""
    if not job.design_dir:
        return False
    folder = Path(job.design_dir)
    return (folder / ("program.gcode" if job.kind == "gcode" else "front.gcode")).is_file()
