"""The print run: what the print task and the operator's commands share about the job on the
printer (one at a time). ``PrintState`` holds the print queue, the ``Run`` in progress and what
outlives one run (the lines acknowledged in the last stream, the rate the printer keeps, the
interrupted jobs resumed and waiting for the print task)."""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ribbond.gcode.alignment import AlignmentRefused
from ribbond.gcode.program import Correction
from ribbond.printer.errors import StreamCancelled
from .programs import Timeline


@dataclass
class MarkCheck:
    """The alignment check of one job: expected mark positions (back-side) and what was measured."""

    expected: np.ndarray
    measured: dict[int, tuple[float, float]] = field(default_factory=dict)
    correction: Correction | None = None        # the accepted fit, once every mark is in
    refused: AlignmentRefused | None = None     # or why it was refused
    fit: dict[str, Any] | None = None           # the fit shown for review (state fitted)
    reseat: bool = False                        # the operator refused the fit under review
    # the marks measured again after a refused fit or a re-seat (the others are kept), numbered from 1
    remeasure: tuple[int, ...] = ()

    current: int = 0                            # the mark the head is above (from 1; 0: on its way)

    def reopen(self, marks: list[int]) -> None:
        """Measure ``marks`` (from 1) again: their measurements, the fit and its verdict dropped."""
        for mark in marks:
            self.measured.pop(mark, None)
        self.remeasure = tuple(sorted(marks))
        self.correction = self.refused = self.fit = None
        self.reseat = False
        self.current = 0

    @property
    def kept(self) -> list[int]:
        """The marks measured and kept (numbered from 1)."""
        return sorted(self.measured)

    @property
    def next_mark(self) -> int | None:
        """The first mark (numbered from 1) not measured yet."""
        missing = [i for i in range(1, len(self.expected) + 1) if i not in self.measured]
        return missing[0] if missing else None


@dataclass(frozen=True)
class ResumePlan:
    """Where an interrupted print goes on (issue 16): ``side`` from part ``start`` (its place in the
    side's program, from 0); ``partial`` the part begun and not proven printed, if any, and what
    the operator chose for it."""

    side: str
    start: int
    parts: int
    partial: int | None = None
    choice: str | None = None
    #: the front is printed and the back not begun, and the operator never said flip-done: the job
    #: goes through the flip step (its instruction, notice, then the alignment), not a frame check
    flip: bool = False


@dataclass
class Stream:
    """The program being streamed: its time line and the measured rate; for a resumed side, where
    it stands in the whole side."""

    side: str
    timeline: Timeline
    acked: int = -1
    program: str = ""                           # what its lines are named by: front, 'back (resumed at part 3)'
    # a resumed side (issue 22): the estimated seconds of the side before this program (its parts
    # proven printed or skipped) and of the whole side; None: this program is the whole side
    base_s: float = 0.0
    side_s: float | None = None
    printing_since: float | None = None         # monotonic, when the first line after heating was acked
    paused_s: float = 0.0
    paused_at: float | None = None


@dataclass
class Run:
    """What the printer task knows of the job it is printing."""

    job_id: str
    flip: asyncio.Event = field(default_factory=asyncio.Event)
    aligned: asyncio.Event = field(default_factory=asyncio.Event)
    alignment: MarkCheck | None = None
    pause_snapshot: dict[str, Any] | None = None
    cancel_requested: bool = False
    stop_reason: str | None = None              # the daemon stops: interrupted, not cancelled
    busy: bool = False                           # pausing or resuming (manual control waits)
    done: asyncio.Event = field(default_factory=asyncio.Event)
    heaters: asyncio.Task[None] | None = None   # the idle-heater policy while waiting
    started: float = field(default_factory=time.time)
    stream: Stream | None = None
    resume: ResumePlan | None = None            # an interrupted print resumed (issue 16)
    checked: asyncio.Event = field(default_factory=asyncio.Event)   # the operator checked the frame
    keep_alignment: bool = False                # ... and it was not moved: the stored correction holds

    def check(self) -> None:
        """Raise ``StreamCancelled`` once a cancel or a stop was asked for."""
        if self.cancel_requested or self.stop_reason is not None:
            raise StreamCancelled(self.stop_reason or "cancelled by the operator")


def stream_rate(stream: Stream) -> float | None:
    """Measured seconds per estimated second since the stream passed its heating (pauses left out)."""
    if stream.printing_since is None:
        return None
    tl = stream.timeline
    estimated = tl.done_s(stream.acked) - tl.done_s(tl.first)
    now = stream.paused_at if stream.paused_at is not None else time.monotonic()
    measured = now - stream.printing_since - stream.paused_s
    if estimated < 0.5 or measured <= 0:
        return None
    return measured / estimated


class PrintState:
    """The print queue and the run on the printer, shared by the components that act on it."""

    def __init__(self) -> None:
        self.queue: asyncio.Queue[str] = asyncio.Queue()
        self.run: Run | None = None
        self.acked = -1                  # program lines acknowledged in the current (or last) stream
        self.commands: list[str] = []    # the commands of that stream (a pause reads its modal state)
        self.rate: float | None = None   # measured seconds per estimated second, from the last stream
        self.resumes: dict[str, ResumePlan] = {}   # interrupted jobs resumed, waiting for the print task
        self.stopping = False            # the daemon stops: no new run begins

    def queue_print(self, job_id: str) -> None:
        """Print the (ready) job after those queued before it."""
        self.queue.put_nowait(job_id)

    def current(self, job_id: str) -> Run | None:
        """The run, if it is ``job_id``'s."""
        run = self.run
        return run if run is not None and run.job_id == job_id else None
