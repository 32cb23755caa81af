"""The heaters around a print: the idle policy while a job waits for the operator (``[flip]``:
keep, lower or off, then all off after ``off_after_s``), the heaters off at a start after an
interrupted print and before a stop, and ``M108`` to end the firmware's heater waits when a job
is stopped while it heats. A printer left by the daemon is never left hot."""

from __future__ import annotations

import asyncio
import contextlib
import logging

from ribbond.printer.errors import LinkError
from ribbond.printer.link import LinkState, PrinterLink
from ..config import FlipPolicy
from ..records import JobRecords, NotFound
from .head import Head
from .run import PrintState, Run

log = logging.getLogger(__name__)


class Heaters:
    """The heater commands the daemon sends on its own (the programs set theirs)."""

    def __init__(self, head: Head, policy: FlipPolicy, records: JobRecords, state: PrintState) -> None:
        self.head, self.policy, self.records, self.state = head, policy, records, state
        self._cooling: asyncio.Task[None] | None = None

    async def idle(self, job_id: str, why: str) -> asyncio.Task[None]:
        """While the job waits for the operator: the heaters follow ``[flip]`` (keep, lower, off)
        now, and all go off after ``off_after_s`` (the task returned; cancel it to keep them)."""
        policy = self.policy
        link = self.head.require_link()
        if policy.heaters == "off":
            await link.send("M104 S0")
        elif policy.heaters == "lower":
            await link.send(f"M104 S{policy.lower_to:.0f}")
        return asyncio.create_task(self._off_later(job_id, why))

    async def idle_until(self, run: Run, job_id: str, why: str, event: asyncio.Event) -> None:
        """Wait for ``event`` (the operator's) with the heaters on the idle policy meanwhile; the
        timer that turns them off is dropped once it is set."""
        run.heaters = await self.idle(job_id, why)
        try:
            await event.wait()
        finally:
            run.heaters.cancel()
            run.heaters = None

    async def _off_later(self, job_id: str, why: str) -> None:
        policy = self.policy
        if policy.off_after_s <= 0:
            return
        link = self.head.require_link()
        try:
            await asyncio.sleep(policy.off_after_s)
            await link.send("M104 S0")
            await link.send("M140 S0")
        except (LinkError, asyncio.TimeoutError) as exc:
            log.warning("job %s: idle heaters: %s", job_id, exc)
            return
        message = f"heaters off after {policy.off_after_s:.0f} s {why}"
        log.info("job %s: %s", job_id, message)
        with contextlib.suppress(NotFound, ValueError):
            self.records.publish(self.records.store.update(job_id, stage=message))
        self.records.bus.publish({"type": "notice", "job_id": job_id, "message": message})

    def cool_after_interruption(self) -> None:
        """The last daemon died with a job on the printer: a board that does not reset when the port
        opens would still be hot over the fabric. Heaters and fan off once it is connected."""
        self._cooling = asyncio.create_task(self._cool(), name="cool")

    async def cooled(self) -> None:
        """Once the heaters-off of ``cool_after_interruption`` (if any) is done."""
        if self._cooling is not None:
            await self._cooling

    async def _cool(self) -> None:
        while not self.head.connected():
            if self.state.stopping:
                return
            await asyncio.sleep(0.1)
        link = self.head.require_link()
        with contextlib.suppress(LinkError, asyncio.TimeoutError):
            async with self.head.lock:
                for command in ("M104 S0", "M140 S0", "M107"):
                    await link.send(command, timeout=10)
            log.info("heaters off: the last daemon stopped with a job on the printer")

    async def off_if_on(self) -> None:
        """No job on the printer, but heaters the operator turned on (``heat``): off before leaving."""
        link = self.head.link
        if link is None or link.state is not LinkState.READY:
            return
        with contextlib.suppress(LinkError, asyncio.TimeoutError):
            temps = await asyncio.wait_for(link.query_temperatures(), 10)
            if any((h.target or 0) > 0 for h in temps.heaters):
                log.info("heaters off before stopping")
                async with self.head.lock:
                    for command in ("M104 S0", "M140 S0"):
                        await link.send(command, timeout=10)

    @staticmethod
    async def break_waits(run: Run, link: PrinterLink) -> None:
        """M109/M190 hold the firmware's queue until hot, and the lines in flight may hold more
        than one: M108 ends each wait (the emergency parser acts on it at arrival, ahead of the
        queue), again until the stream has ended."""
        while not run.done.is_set() and link.state in (LinkState.STREAMING, LinkState.PAUSED) \
                and run.stream is not None:
            await link.send("M108", timeout=30)
            await asyncio.sleep(0.3)
