"""The print task: one job on the printer at a time, from the print queue (``PrintState``).

It drives a job through heating and the front program, the flip and the alignment check
(``Aligner``), the back program re-rendered with the fitted correction, done; a plain G-code
program is streamed the same way, a resumed job (``Resumer``) from the part it stood at. What the
printer acknowledged is queued, not executed: ``last_acked_line`` is recorded as streaming goes,
and the synchronized checkpoints (after ``M400``: the front done, the flip, a safe stop) say exactly
where an interrupted job stood. A stop of the daemon (``shutdown``), a cancel or a fatal error of
the task ends the stream at a line boundary, turns the heaters off and lifts the head
(``_safe_stop``); the job is ``cancelled`` or ``interrupted``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ribbond.design.folder import read_design_folder
from ribbond.design.format import Design
from ribbond.gcode.alignment import expected_marks
from ribbond.gcode.profiles import PrinterProfile
from ribbond.gcode.program import Correction, Program, SidePlan, render_side
from ribbond.printer.errors import Disconnected, LinkError, StreamCancelled
from ribbond.printer.link import LinkState, PrinterLink, prepare_program
from ribbond.printer.sender import StreamProgress
from ..jobs import JobState
from ..records import JobRecords, NotFound
from ..store import FRAME_FRESH, JobRecord, JobStore
from .aligner import Aligner
from .frame import FrameGate, needs_fresh_frame
from .head import Head
from .heaters import Heaters
from .programs import Part, program_parts, program_timeline
from .resume import Resumer, resumed_text
from .run import PrintState, Run, Stream, stream_rate

log = logging.getLogger(__name__)

#: Acknowledged-line checkpoints are written at most this often while streaming, seconds.
ACK_INTERVAL_S = 0.5
#: How long a stop of the daemon waits for the safe stop before the emergency stop, seconds
#: (systemd's TimeoutStopSec is 30).
STOP_TIMEOUT_S = 20.0


class _PartTracker:
    """Records a streaming program's parts in the store as their lines are acknowledged."""

    def __init__(self, store: JobStore, job_id: str, side: str, parts: list[Part], base: int) -> None:
        self.store, self.job_id, self.side, self.parts, self.base = store, job_id, side, parts, base
        self.barriers = frozenset(p.first_e for p in parts if p.first_e is not None)
        self._next_start = self._next_done = 0

    def acknowledged(self, count: int) -> None:
        """The first ``count`` program lines are acknowledged (called before the sender sends more)."""
        parts = self.parts
        while self._next_start < len(parts) and (parts[self._next_start].first_e or 0) <= count:
            part = parts[self._next_start]
            if part.first_e is not None:
                # not fsynced: it must be committed before the line goes out, and the printer waits
                self.store.record_part(self.job_id, self.side, self.base + part.ordinal, "started",
                                       part.first_e, durable=False)
            self._next_start += 1
        while self._next_done < len(parts) and parts[self._next_done].sync is not None \
                and parts[self._next_done].sync < count:                           # type: ignore[operator]
            part = parts[self._next_done]
            self.store.record_part(self.job_id, self.side, self.base + part.ordinal, "done", part.sync)
            self._next_done += 1


class _Acknowledgements:
    """What each acknowledgement of a streaming program does (the sender's progress callback): the
    parts recorded, the switch from ``heating`` to ``after_heating`` where the program starts
    printing, ``last_acked_line`` stored and a progress event sent at most every ACK_INTERVAL_S."""

    def __init__(self, records: JobRecords, state: PrintState, progress: Callable[[JobRecord], dict[str, Any]],
                 job_id: str, stream: Stream, track: _PartTracker, after_heating: JobState | None,
                 frame_used: Callable[[str], None]) -> None:
        self.records, self.state, self.progress, self.job_id = records, state, progress, job_id
        self.stream, self.track, self.after_heating = stream, track, after_heating
        self.frame_used, self._printed = frame_used, False
        self.switched = after_heating is None
        self._last_write = 0.0
        if self.switched:
            stream.printing_since = time.monotonic()

    def __call__(self, p: StreamProgress) -> None:
        records, stream, job_id, side = self.records, self.stream, self.job_id, self.stream.side
        first_part = stream.timeline.first
        now = time.monotonic()
        self.state.acked = stream.acked = p.acknowledged
        self.track.acknowledged(p.acknowledged)
        if stream.printing_since is None and p.acknowledged >= first_part:
            stream.printing_since = now
        if not self._printed and p.acknowledged >= first_part:
            self._printed = True
            self.frame_used(job_id)                   # the program prints on the frame: it is no longer fresh
        if not self.switched and p.acknowledged >= first_part:
            self.switched = True
            job = records.get(job_id)
            if job.state is JobState.HEATING and self.after_heating is not None:   # (not switched: it is set)
                what = "the program" if stream.program == "program" else side   # a plain program has no sides
                records.transition(job_id, self.after_heating, stage=f"printing {what}")
        if now - self._last_write >= ACK_INTERVAL_S or p.acknowledged == p.total:
            self._last_write = now
            # the progress of the line stored with it: what a restart finds is never less than shown
            job = records.get(job_id)
            info = self.progress(job.model_copy(update={"last_acked_line": max(p.acknowledged, job.last_acked_line)}))
            records.store.record_ack(job_id, p.acknowledged, info["progress"])
            records.bus.publish({"type": "progress", "job_id": job_id, "side": side, "program": stream.program,
                                 "line": p.acknowledged, "lines": p.total, **info})


class PrintTask:
    """The print task and the stops of the job it prints. ``progress`` is how far a job is (the
    service's ``progress``), sent with the stream's progress events."""

    def __init__(self, head: Head, profile: PrinterProfile, records: JobRecords, state: PrintState,
                 heaters: Heaters, aligner: Aligner, resumer: Resumer,
                 progress: Callable[[JobRecord], dict[str, Any]], frame: FrameGate) -> None:
        self.head, self.profile, self.records, self.state = head, profile, records, state
        self.heaters, self.aligner, self.resumer, self.progress = heaters, aligner, resumer, progress
        self.frame = frame
        self._background_tasks: set[asyncio.Future[Any]] = set()

    # ------------------------------------------------------------------ the queue

    async def run(self) -> None:
        """The print task: the queued jobs one after the other, for the daemon's life."""
        state = self.state
        while True:
            job_id = await state.queue.get()
            try:
                job = self.records.get(job_id)
            except NotFound:
                continue                                      # deleted while queued
            resume = state.resumes.pop(job_id, None)
            if resume is not None and job.state is JobState.AWAITING_CHECK:
                state.run = run = Run(job_id, resume=resume)
                await self._run_print(run, job)
                continue
            if job.state is not JobState.READY or not job.start_when_ready:
                continue
            if state.stopping:
                continue                                      # the daemon stops: queued again at its next start
            if not self.head.connected():                     # wait for the printer, do not fail
                waited = await self._wait_for_printer(job_id)
                if waited is None:
                    continue
                job = waited
            if needs_fresh_frame(job) and self.records.store.frame()["state"] != FRAME_FRESH:
                gated = await self.frame.wait_fresh(job_id)   # not over the fabric the last job left
                if gated is None:
                    continue
                job = gated
            state.run = run = Run(job_id)
            await self._run_print(run, job)

    async def _wait_for_printer(self, job_id: str) -> JobRecord | None:
        """Wait until the printer is connected; the job then, or None if it is no longer to print."""
        records, state = self.records, self.state
        log.info("job %s waits for the printer to connect", job_id)
        records.publish(records.store.update(job_id, stage="waiting for the printer"))
        while not self.head.connected() and not state.stopping and records.exists(job_id) \
                and records.get(job_id).state is JobState.READY:
            await asyncio.sleep(0.2)
        if not records.exists(job_id) or records.get(job_id).state is not JobState.READY or state.stopping:
            return None
        return records.store.update(job_id, stage=None)

    async def _run_print(self, run: Run, job: JobRecord) -> None:
        try:
            await self._print(job)
        except StreamCancelled:
            await self._end_run_logged(run, None)
        except Exception as exc:  # noqa: BLE001 - any fatal error of the print task: stop safely
            if isinstance(exc, Disconnected):                 # the link logged it in one line
                log.debug("printing job %s", job.id, exc_info=True)
            else:
                log.exception("printing job %s", job.id)
            kind = "printer" if isinstance(exc, (LinkError, OSError)) else "internal error"
            await self._end_run_logged(run, f"{kind}: {exc}")
        finally:
            if run.heaters is not None:
                run.heaters.cancel()
            self.state.run = None
            run.done.set()

    async def _end_run_logged(self, run: Run, error: str | None) -> None:
        try:
            await self._end_run(run, error)
        except Exception:  # noqa: BLE001 - the print queue goes on with the next job
            log.exception("ending the run of job %s", run.job_id)

    async def _end_run(self, run: Run, error: str | None) -> None:
        """After the stream ended early: heaters off, head lifted; the job ``cancelled`` (asked for),
        or ``interrupted`` (the daemon stops, or ``error``) with the exact checkpoint."""
        records = self.records
        stopped = await self._safe_stop()
        job = records.get(run.job_id)
        if job.state.terminal:
            return
        if run.cancel_requested and error is None:
            records.transition(run.job_id, JobState.CANCELLED, reason="cancelled by the operator",
                               start_when_ready=False, stage="cancelled: heaters off, head lifted" if stopped else None)
            return
        reason = error or run.stop_reason or "stopped"
        if stopped and job.state in (JobState.HEATING, JobState.PRINTING_FRONT, JobState.PRINTING_BACK,
                                     JobState.PAUSED):
            # after M400 every acknowledged line has been executed: the checkpoint is exact
            side = job.side or "front"
            records.store.record_ack(run.job_id, self.state.acked)
            records.store.checkpoint(run.job_id, f"{side}_stopped", self.state.acked)
        records.transition(run.job_id, JobState.INTERRUPTED, reason=reason, start_when_ready=False,
                           stage="stopped: heaters off, head lifted" if stopped else "stopped")

    # ------------------------------------------------------------------ one job

    async def _print(self, job: JobRecord) -> None:
        link = self.head.require_link()
        run = self.state.run
        assert run is not None
        if job.kind == "gcode":
            text = Path(job.mesh_path).read_text(encoding="utf-8")
            self.records.transition(job.id, JobState.HEATING, side="front", stage="heating")
            await self._stream(job.id, text, "front", JobState.PRINTING_FRONT, plain=True)
            await self._side_done(job.id, run, link, "program_done")
            self._done(job.id)
            return
        design = read_design_folder(Path(job.design_dir or "")).design
        has_back = any(r.side == "back" for r in design.ribbons or [])
        if run.resume is not None:
            await self.resumer.check_frame(job.id)
        if run.resume is None or run.resume.side == "front":
            await self._print_front(job, run, link)
            if not has_back:
                self._done(job.id)
                return
        await self._print_back(job, run, link, design)

    async def _print_front(self, job: JobRecord, run: Run, link: PrinterLink) -> None:
        """Heat and print the front (a resumed front from its part), to its checkpoint."""
        resume = run.resume
        front = (Path(job.design_dir or "") / "front.gcode").read_text(encoding="utf-8")
        start = resume.start if resume is not None else 0
        whole = await self._resumed_side(front, start)
        if start:
            front = resumed_text(front, "front", start, resume, self.profile)
        self.records.transition(job.id, JobState.HEATING, side="front", stage="heating")
        await self._stream(job.id, front, "front", JobState.PRINTING_FRONT, part_base=start, whole=whole)
        await self._side_done(job.id, run, link, "front_done")

    async def _print_back(self, job: JobRecord, run: Run, link: PrinterLink, design: Design) -> None:
        """The flip and the alignment (or, resumed with ``keep_alignment``, the stored correction),
        then the back re-rendered with the correction (a resumed back from its part); done."""
        resume = run.resume
        expected = expected_marks(design.registration_marks or [], self.profile.frame)
        if len(expected) < 2:
            raise ValueError(f"the design has {len(expected)} registration marks: the back side cannot be "
                             "aligned (at least 2 are needed)")
        kept = resume is not None and resume.side == "back" and run.keep_alignment and job.correction
        if kept:
            correction = Correction.model_validate(job.correction)
        else:
            # a resumed back: the frame is back side up already (the operator checked it), unless the
            # front was printed and the frame never turned over: then the flip step first
            flipped = resume is not None and resume.side == "back" and not resume.flip
            correction = await self.aligner.align(job.id, expected, flipped=flipped)
        program = self._corrected_back(job.id, correction)
        start = resume.start if resume is not None and resume.side == "back" else 0
        whole = await self._resumed_side(program.text, start)
        text = resumed_text(program.text, "back", start, resume, self.profile) if start else program.text
        # the front's lines are not the back's: until the back's stream sets them, no line count is shown
        fields: dict[str, Any] = dict(side="back", correction=correction.model_dump(mode="json"), error=None,
                                      estimate_s={**(job.estimate_s or {}), "back": float(program.stats.time_s)},
                                      program="back", lines_total=None, last_acked_line=-1)
        if kept:
            self.records.transition(job.id, JobState.HEATING, stage="heating", **fields)
            await self._stream(job.id, text, "back", JobState.PRINTING_BACK, part_base=start, whole=whole)
        else:
            self.records.transition(job.id, JobState.PRINTING_BACK, stage="printing back", **fields)
            await self._stream(job.id, text, "back", None, part_base=start, whole=whole)
        await self._side_done(job.id, run, link, "back_done")
        self._done(job.id)

    async def _resumed_side(self, text: str, start: int) -> tuple[float, float] | None:
        """For a side resumed at part ``start`` (> 0): the estimated seconds of the whole side's
        program before that part and in all (the resumed program's progress adds to the first);
        None when the side prints from its beginning."""
        if not start:
            return None
        lines = text.splitlines()
        timeline = await asyncio.to_thread(program_timeline, lines, self.profile)
        # (both count commands: a part begins at its command's place)
        return timeline.done_s(program_parts(lines)[start].begin), timeline.total

    def _corrected_back(self, job_id: str, correction: Correction) -> Program:
        """The back program rendered with ``correction``, kept as the job's ``back-corrected.gcode``
        (written whole: a resume reads it)."""
        plan = SidePlan.load(self.records.dir(job_id) / "plans" / "back-plan.npz")
        program = render_side(plan, self.profile, correction=correction)
        corrected = self.records.dir(job_id) / "back-corrected.gcode"
        tmp = corrected.with_suffix(".tmp")
        tmp.write_text(program.text, encoding="utf-8")
        os.replace(tmp, corrected)
        return program

    async def _side_done(self, job_id: str, run: Run, link: PrinterLink, checkpoint: str) -> None:
        """A program streamed to its end: once executed (``M400``), its checkpoint."""
        await link.send("M400", timeout=600)
        self.records.publish(self.records.store.checkpoint(job_id, checkpoint, self.state.acked))
        run.check()

    def _done(self, job_id: str) -> None:
        self.records.transition(job_id, JobState.DONE, stage=None, progress=None, start_when_ready=False)

    async def _stream(self, job_id: str, text: str, side: str, after_heating: JobState | None,
                      plain: bool = False, part_base: int = 0, whole: tuple[float, float] | None = None) -> None:
        """Stream one program; switch from ``heating`` to ``after_heating`` where it starts printing.

        A design's program records its parts (numbered from ``part_base``: a resumed program starts
        at a later part) in the store as they go: ``started`` before the first line that feeds
        filament goes out (a barrier of the sender), ``done`` when the part's ``M400`` is
        acknowledged: two writes a part, none a line."""
        link = self.head.require_link()
        run, state, records = self.state.run, self.state, self.records
        assert run is not None
        run.check()
        lines = text.splitlines()
        commands = prepare_program(lines, f"{side}.gcode")
        timeline = await asyncio.to_thread(program_timeline, lines, self.profile)
        # asked while the time line was computed: the link had no stream to cancel, so none begins
        run.check()
        name = "program" if plain else side + (f" (resumed at part {part_base + 1})" if whole is not None else "")
        stream = run.stream = Stream(side=side, timeline=timeline, program=name)
        if whole is not None:
            stream.base_s, stream.side_s = whole
        state.commands = commands
        state.acked = -1
        self.head.forget()
        records.publish(records.store.update(job_id, lines_total=len(commands), last_acked_line=-1, program=name))
        track = _PartTracker(records.store, job_id, side, [] if plain else program_parts(lines), part_base)
        acks = _Acknowledgements(records, state, self.progress, job_id, stream, track, after_heating, self.frame.used)
        ran = 0

        def progress(p: StreamProgress) -> None:
            nonlocal ran                                  # the program's G28 and M84: the axes homed
            if p.acknowledged > ran:
                self.head.ran(commands[ran:p.acknowledged])
                ran = p.acknowledged
            acks(p)

        try:
            await link.stream(commands, progress, track.barriers)
        finally:
            rate = stream_rate(stream)
            if rate is not None and stream.acked >= len(commands) - 1:
                state.rate = rate                             # what this printer does with an estimate
            run.stream = None
        if not acks.switched and after_heating is not None:
            records.transition(job_id, after_heating, stage="printing the program" if plain else f"printing {side}")
            self.frame.used(job_id)

    # ------------------------------------------------------------------ stops

    def _safe_stop_commands(self) -> list[str]:
        """Heaters off, fan off, the head lifted by the profile's park lift, motion finished, motors off."""
        return ["M104 S0", "M140 S0", "M107", "G91",
                f"G0 Z{self.profile.park_lift:.3f} F{self.profile.motion.z_speed * 60:.0f}", "G90", "M400", "M84"]

    async def _safe_stop(self) -> bool:
        """Heaters off, head lifted: after a cancel, a stop or a failure. Whether it was sent."""
        link = self.head.link
        if link is None or link.state not in (LinkState.READY, LinkState.STREAMING, LinkState.PAUSED):
            return False
        sent = True
        async with self.head.lock:
            for command in self._safe_stop_commands():
                try:
                    await link.send(command, timeout=60)
                except (LinkError, asyncio.TimeoutError):
                    sent = False
            self.head.forget()
            self.head.ran(self._safe_stop_commands())            # the motors off: no axis homed
        return sent

    async def shutdown(self, reason: str) -> None:
        """Stop safely before the daemon exits: a job on the printer ends its stream at a line
        boundary, the heaters go off, the head is lifted by the profile's park lift, and the job is
        ``interrupted`` with an exact checkpoint. If that does not finish in ``STOP_TIMEOUT_S``,
        the emergency stop (M112: heaters off in the firmware)."""
        self.state.stopping = True
        run = self.state.run
        if run is None:
            await self.heaters.off_if_on()
            return
        run.stop_reason = reason
        self.interrupt(run)
        try:
            await asyncio.wait_for(run.done.wait(), STOP_TIMEOUT_S)
        except asyncio.TimeoutError:
            log.error("the safe stop did not finish in %.0f s: emergency stop", STOP_TIMEOUT_S)
            with contextlib.suppress(Exception):
                if self.head.link is not None:
                    self.head.link.emergency_stop()

    def interrupt(self, run: Run) -> None:
        """Make the print task leave what it waits on (the stream, a heater wait, the flip, the marks)."""
        link = self.head.link
        if link is not None and link.state in (LinkState.STREAMING, LinkState.PAUSED):
            with contextlib.suppress(NotFound):
                if self.records.get(run.job_id).state is JobState.HEATING and link.capabilities.emergency_parser:
                    self._background(self.heaters.break_waits(run, link), "M108")
            with contextlib.suppress(LinkError):
                link.cancel()
        run.flip.set()
        run.aligned.set()
        run.checked.set()
        if run.heaters is not None:
            run.heaters.cancel()

    def _background(self, coroutine: Any, what: str) -> None:
        """Run ``coroutine`` without waiting for it; its failure is logged."""
        task = asyncio.ensure_future(coroutine)

        def done(t: asyncio.Future[Any]) -> None:
            if not t.cancelled() and t.exception() is not None:
                log.warning("%s: %s", what, t.exception())

        task.add_done_callback(done)
        self._background_tasks.add(task)
        task.add_done_callback(self._background_tasks.discard)
