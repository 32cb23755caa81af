"""The sender: numbered lines out, acknowledgements in, flow control, resends and timeouts.

It is a go-back-N sender over Marlin's line-number protocol:

* Every command gets the next line number and a checksum and stays in a bounded history until it
  can no longer be asked for again.
* A line goes out only while the printer can take it: no more lines in flight than its command
  queue has slots (learned from the free counts ADVANCED_OK reports, Marlin's default of 4
  otherwise), so that no line waits in its receive buffer, and no more unacknowledged bytes than
  the byte window (``Capabilities.rx_buffer_bytes``, shrunk by ``window.WindowGovernor`` when a
  trial proves the board's buffer smaller), counting every byte as if it were still in that buffer. Ping-pong
  (one line in flight) is the fallback and an option.
* ``Resend: N`` rewinds to N, once. The sender first holds: every request that arrives meanwhile
  comes from the stale lines sent after N (each is rejected, or cut by the buffer flush the error
  causes) and only moves the target to the latest line asked for. The hold ends the moment each
  line sent after the target has drawn its request (Marlin answers each with one), or, when the
  flush ate some silently, once the bytes already sent have had time to reach the printer (their
  wire time plus a settle margin). Then it resends from there. It never resends at once and
  swallows the repeats: with the printer's queue full, stale lines still waiting in its receive
  buffer would flush the resent ones (the "resend death loop" of Marlin PRs #24959/#24972).
  An ``ok`` without a line number during a pending resend acknowledges nothing at or above N (Marlin
  2.x answers the tail of a cut line as an unnumbered command). The request that answers a
  line-check error may not ask past the line that error refused: that line would never run. No request after the hold is ever ignored, so a
  resent line destroyed by a later flush is asked for, and sent, again. The plain ``ok`` Marlin
  prints after each request acknowledges nothing.
  The firmware's line-number check guarantees that a line it accepted is never executed again; the
  sender's part is never to give one command two numbers and never to resend a line the printer
  had already acknowledged (that means the printer lost its state).
* When nothing at all comes back for a while (a lost ``ok``), a numbered ``M105`` probe goes out:
  either the printer asks for a lost line, or its ``ok T:…`` proves that everything before the probe
  was processed. A printer that stays silent through several probes is reported, not waited on.

* Per dialect (``Capabilities``): a firmware that answers an empty line (Smoothieware) is never
  nudged; Repetier's ``skip N`` (a stale or repeated line ignored) counts as a stale line's refusal
  and the ``ok`` after it acknowledges nothing; its ``wait`` (idle) probes lines still unacknowledged
  at once; a firmware whose ``ok`` only says "received" (Repetier) has a command's answer wait for
  a proof that it ran (:mod:`.proof`: an ``M114`` sent after it reports its position), and a
  program's ``M400`` counts only once proven, the program's next lines waiting for it; a firmware
  that drops a bad line without a word (RepRapFirmware 3) is stopped, naming the lines, when a
  query's answer shows that an earlier line was never acknowledged (an ``M105`` follows each
  ``M400`` there, so that a part does not count as printed before that is known).

The sender parses nothing: it takes events from :mod:`.codec` and writes bytes to a callable.
"""

from __future__ import annotations

import asyncio
import logging
import re
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from pydantic import BaseModel, Field

from . import codec
from .capabilities import Capabilities
from .errors import LinkError, PrinterSilent, ProtocolError, StreamCancelled
from .proof import RunProofs, at_position, expected_position
from .window import WindowGovernor

log = logging.getLogger(__name__)

PROBE_COMMAND = "M105"
_LINE_NUMBER_RESET = "M110 N0"
#: Commands whose ``ok`` is their whole answer even where ``ok`` means "received": ``M110`` is done
#: on receipt (Repetier's checkAndPushCommand), and the link waits for the queries' reports itself.
_ANSWERED_ON_RECEIPT = ("M110", "M105", "M114")


class Timeouts(BaseModel):
    """How long the printer may say nothing at all before the sender probes it, per kind of
    command (the oldest unacknowledged one decides). Any line from the printer (``busy:``, a
    temperature report, an ``ok``) restarts the clock."""

    default_s: float = Field(default=8.0, gt=0)
    #: Homing, leveling, M400 and dwells: the printer may be quiet while the machine moves.
    motion_wait_s: float = Field(default=300.0, gt=0)
    #: Heating waits (M109, M190, …): Marlin reports temperatures, other firmwares may not.
    heating_s: float = Field(default=1200.0, gt=0)
    #: Probes sent before the printer is declared silent.
    probes: int = Field(default=3, ge=1)
    #: After a resend request, wait this long beyond the wire time of the bytes already sent before
    #: resending (USB serial bridges buffer for up to ~16 ms each way).
    resend_settle_s: float = Field(default=0.04, ge=0)
    #: Silence after which a bare newline goes out, once: if noise turned the last line's newline
    #: into another byte, the printer waits for the rest of that line and would answer nothing
    #: until the probe. An empty line is ignored by the firmware otherwise, so a nudge in a silence
    #: that had another cause (a long move) costs one byte: far below what streaming answers take
    #: to come back (a few ms at 250000 baud), 30 ms is already a stall. 0 disables it.
    nudge_s: float = Field(default=0.03, ge=0)

    def for_command(self, command: str) -> float | None:
        """Seconds of silence allowed while ``command`` is the oldest unacknowledged one; None
        for waits on the user (``M0``/``M1``), which may last as long as the user takes."""
        word = _command_word(command)
        if word in ("M0", "M1"):
            return None
        if word in ("M109", "M190", "M191", "M116", "M303"):
            return self.heating_s
        if word in ("G28", "G29", "G30", "G33", "G34", "M400", "M48"):
            return self.motion_wait_s
        if word == "G4":
            return self.default_s + _dwell_seconds(command)
        return self.default_s


_WORD = re.compile(r"^\s*([GMTgmt]\d+)")


def _keeps_alive(event: codec.Event) -> bool:
    """Whether an event shows that the printer is working on our commands (unsolicited reports
    such as temperature autoreports and echo lines do not)."""
    if isinstance(event, codec.TemperatureReport):
        return event.waiting
    return isinstance(event, (codec.Busy, codec.Error, codec.Position, codec.FirmwareInfo,
                              codec.Capability, codec.UnknownCommand, codec.Skip))


def _command_word(command: str) -> str:
    match = _WORD.match(command)
    return match.group(1).upper() if match else ""


def _dwell_seconds(command: str) -> float:
    seconds = re.search(r"\bS(\d+(?:\.\d+)?)", command)
    millis = re.search(r"\bP(\d+(?:\.\d+)?)", command)
    return (float(seconds.group(1)) if seconds else 0.0) + (float(millis.group(1)) / 1000 if millis else 0.0)


@dataclass
class Answer:
    """What the printer said about one command: the lines it printed while the command was the
    oldest unacknowledged one, and the acknowledgement."""

    command: str
    line: int
    events: list[codec.Event]
    ok: codec.Ok

    def first(self, kind: type) -> codec.Event | None:
        for event in self.events:
            if isinstance(event, kind):
                return event
        return None


@dataclass
class StreamProgress:
    """Progress of a stream: ``acknowledged`` of ``total`` program lines."""

    total: int
    sent: int
    acknowledged: int
    resends: int
    elapsed_s: float


@dataclass
class StreamResult:
    lines: int
    resends: int
    elapsed_s: float
    probes: int
    #: The byte window at the end (smaller than configured after an overflow verdict).
    window_bytes: int = 0
    window_verdict: str = "none"
    #: Bare newlines sent after silences (the sender's lifetime, as resends and probes).
    nudges: int = 0


@dataclass(eq=False)
class _Line:
    number: int
    command: str
    data: bytes
    program_index: int | None = None  # index in the running program, None for other commands
    offset: int | None = None  # unacknowledged bytes, this line included, when it was last sent
    future: asyncio.Future[Answer] | None = None
    events: list[codec.Event] = field(default_factory=list)
    receipt: codec.Ok | None = None  # its ok, when its answer waits for a proof that it ran


@dataclass(frozen=True)
class _Fresh:
    """A command not yet numbered: one from ``send`` (with its future) or a follow-up query ahead
    of the program, or program line ``program_index``. It becomes a ``_Line`` once numbered."""

    command: str
    future: asyncio.Future[Answer] | None = None
    program_index: int | None = None


@dataclass
class _Hold:
    """A resend request being held (see the module's docstring): the timer that ends it, the latest
    line asked for, and the requests the stale lines sent after that line draw."""

    timer: asyncio.TimerHandle
    target: int
    stale_expected: int
    stale_seen: int = 0


@dataclass
class _ResentProof:
    """``M400`` + ``M114`` sent behind a re-sent line that drew no ``ok`` (plain-ok firmware):
    the report says whether the printer is where the program is after that line."""

    line: _Line
    query: int  # the M114's line number
    expected: dict[str, float]
    report: codec.Position | None = None


@dataclass
class _Program:
    commands: Sequence[str]
    progress: Callable[[StreamProgress], None] | None
    done: asyncio.Future[StreamResult]
    started: float
    next_index: int = 0
    acknowledged: int = 0
    cancelled: bool = False
    paused: bool = False
    barriers: frozenset[int] = frozenset()  # indices sent only once every line before is acknowledged


class Sender:
    """Sends commands to a Marlin-style printer with flow control and resends.

    Parameters
    ----------
    write
        Hands bytes to the transport.
    capabilities
        The firmware's capabilities; updated from acknowledgements as they arrive.
    timeouts
        Silence allowed before probing.
    ping_pong
        Keep at most one line in flight (the classic host behaviour).
    history
        Lines kept for resends.
    baud
        The line's baud rate, to know how long bytes already sent take to reach the printer.
    """

    def __init__(
        self,
        write: Callable[[bytes], None],
        capabilities: Capabilities,
        *,
        timeouts: Timeouts | None = None,
        ping_pong: bool = False,
        history: int = 1024,
        baud: int = 115200,
    ) -> None:
        self._byte_time = 10 / baud
        self._write = write
        self.capabilities = capabilities
        self.timeouts = timeouts or Timeouts()
        self.ping_pong = ping_pong
        self._history_size = history
        self._history: dict[int, _Line] = {}
        self._history_floor = 0  # lowest number that may still be in the history
        self._next_number = 0  # number the next new command gets
        self._cursor = 0  # number of the next line to transmit (rewound by resends)
        self._inflight: deque[_Line] = deque()  # transmitted, not acknowledged, ascending numbers
        self._inflight_bytes = 0
        self._acked_through = -1  # highest line number known processed by the printer
        self._singles: deque[_Fresh] = deque()  # commands from send(), ahead of the program
        self._program: _Program | None = None
        self._failure: LinkError | None = None
        self._hold: _Hold | None = None
        self._resend_ok_due = False
        # Lines asked for again and not yet acknowledged. Each request is for a line the printer does
        # not hold (it holds every line before it): all stay here until their own acknowledgement.
        self._asked_again: set[int] = set()
        self._refused: int | None = None  # the line the last line-check Error refused
        self._unproven: int | None = None  # a re-sent line the printer asked past, unacknowledged
        self._solo: int | None = None  # plain-ok firmware: a re-sent line sent alone until its ok
        self._resent_proof: _ResentProof | None = None  # its ok did not come: the position decides
        self._skip_oks = 0  # Repetier: oks due after "skip N" lines, which acknowledge nothing
        self._tail_oks = 0  # Marlin 2.x: oks due after cut tails run as unknown commands
        self._last_query = -1  # the last line a query's answer acknowledged by name
        self._proofs: RunProofs[_Line] = RunProofs()  # where ok means "received" (proof.py)
        self._run_hold: _Line | None = None  # a program M400 whose run the program waits for
        self._last_heard = time.monotonic()
        self._nudged_at: float | None = None  # the _last_heard of the silence already nudged
        self._nudge_behind: int | None = None  # a nudge's byte waits behind this line in the buffer
        self._probes_outstanding = 0
        self._watchdog: asyncio.Task[None] | None = None
        # Statistics for reports and benchmarks.
        self.resends = 0
        self.probes = 0
        self.nudges = 0
        self.window = WindowGovernor(capabilities.rx_buffer_bytes)

    # ------------------------------------------------------------------ public API

    def start(self) -> None:
        """Start the silence watchdog (call from the running loop)."""
        if self._watchdog is None:
            self._watchdog = asyncio.get_running_loop().create_task(self._watch())

    def stop(self, reason: LinkError) -> None:
        """Fail everything outstanding with ``reason`` and stop sending."""
        if self._failure is None:
            self._failure = reason
        waiting = self._proofs.clear() + self._history_from(self._acked_through + 1)
        for future in [line.future for line in waiting] + [fresh.future for fresh in self._singles]:
            if future is not None and not future.done():
                future.set_exception(reason)
        self._inflight.clear()
        self._inflight_bytes = 0
        self._singles.clear()
        self._solo = self._resent_proof = None
        if self._program is not None and not self._program.done.done():
            self._program.done.set_exception(reason)
        self._program = None
        if self._watchdog is not None:
            self._watchdog.cancel()
            self._watchdog = None
        if self._hold is not None:
            self._hold.timer.cancel()
            self._hold = None

    @property
    def in_flight(self) -> int:
        return len(self._inflight)

    @property
    def last_acknowledged_line(self) -> int:
        return self._acked_through

    def reset_line_numbers(self) -> asyncio.Future[Answer]:
        """Send ``M110 N0`` as line 0 and number what follows from 1 (the connection handshake)."""
        if self._inflight or self._singles or self._program is not None:
            raise LinkError("cannot reset line numbers while commands are outstanding")
        self._history.clear()
        self._history_floor = 0
        self._next_number = 0
        self._cursor = 0
        self._acked_through = -1
        self._resend_ok_due = False
        self._asked_again.clear()
        self._unproven = self._solo = self._resent_proof = None
        self._skip_oks = self._tail_oks = 0
        self._last_query = -1
        self._run_hold = None
        for line in self._proofs.clear():  # a reset or a new handshake: they will never be proven
            if line.future is not None and not line.future.done():
                line.future.set_exception(LinkError("line numbers reset before the command was proven run"))
        self._nudge_behind = None  # numbers restart: an old nudge's line would never be acknowledged
        return self.send(_LINE_NUMBER_RESET)

    def send(self, command: str) -> asyncio.Future[Answer]:
        """Queue one command ahead of any running program; the future gives its answer."""
        self._raise_if_failed()
        command = codec.strip_comment(command)
        codec.check_sendable(command)
        future: asyncio.Future[Answer] = asyncio.get_running_loop().create_future()
        self._singles.append(_Fresh(command, future))
        self._pump()
        return future

    def stream(
        self,
        commands: Sequence[str],
        progress: Callable[[StreamProgress], None] | None = None,
        barriers: frozenset[int] = frozenset(),
    ) -> asyncio.Future[StreamResult]:
        """Start streaming ``commands`` (already stripped of comments and blank lines); the future
        completes when every one of them was acknowledged. Program line i in ``barriers`` goes out
        only once every line before it is acknowledged and ``progress`` has been told so (the
        host records something before the printer may act on line i)."""
        self._raise_if_failed()
        if self._program is not None:
            raise LinkError("a program is already streaming")
        loop = asyncio.get_running_loop()
        done: asyncio.Future[StreamResult] = loop.create_future()
        self._program = _Program(commands, progress, done, time.monotonic(), barriers=frozenset(barriers))
        self._report_progress()
        if not commands:
            self._finish_program()
        self._pump()
        return done

    def pause(self) -> None:
        """Stop feeding program lines (lines in flight still complete; resends still go out)."""
        if self._program is not None:
            self._program.paused = True

    def resume(self) -> None:
        if self._program is not None:
            self._program.paused = False
        self._pump()

    def cancel(self) -> None:
        """Stop the program: no further lines are sent; it ends with StreamCancelled once the
        lines in flight are acknowledged."""
        if self._program is None:
            return
        self._program.cancelled = True
        self._maybe_finish_program()

    # ------------------------------------------------------------------ events from the printer

    def handle(self, event: codec.Event) -> None:
        """Take one event parsed from the printer's output."""
        if isinstance(event, (codec.Ok, codec.Resend)):
            self._last_heard = time.monotonic()
            self._probes_outstanding = 0
        elif _keeps_alive(event):
            self._last_heard = time.monotonic()
        if self._resent_proof is not None and self._on_proof_event(event):
            return
        if isinstance(event, codec.Ok):
            self._refused = None  # no request followed the error
            self._on_ok(event)
        elif isinstance(event, codec.Resend):
            self._on_resend(event.line)
        elif isinstance(event, codec.Skip):
            self._on_skip()
        elif isinstance(event, codec.Wait):
            self._on_wait()
        else:
            if isinstance(event, codec.UnknownCommand) and "*" in event.command:
                # the tail of a line cut by a flush (a checksum; the link never sends a "*"
                # otherwise): its plain ok is no line's, even once the resend went out
                self._tail_oks += 1
            if isinstance(event, codec.Error):
                self._on_line_error(event)
            # Output comes before the ok of the command it answers, or, where ok means "received",
            # after it: then it belongs to the oldest command not yet proven run.
            oldest = self._proofs.oldest_unproven or self._history.get(self._acked_through + 1)
            if oldest is not None and oldest.number < self._next_number:
                oldest.events.append(event)
            if isinstance(event, codec.Position) and self.capabilities.ok_means == "received":
                self._complete_runs(self._proofs.position_reported())

    def _on_skip(self) -> None:
        """Repetier ignored a line (one sent after a line it asked for again, or one it already
        has) and says so with ``skip N`` and an ``ok``: during a resend hold it is one of the stale
        lines' answers, as Marlin's repeated requests are; its ``ok`` acknowledges nothing."""
        self._skip_oks += 1
        hold = self._hold
        if hold is not None:
            hold.stale_seen += 1
            if hold.stale_seen >= hold.stale_expected:
                hold.timer.cancel()
                self._end_hold()

    def _on_wait(self) -> None:
        """``wait``: the printer's command buffer has been empty for a second. Everything it
        received has run; a line still unacknowledged was lost, or its ``ok`` was: probe now
        rather than after the silence timeout."""
        unanswered = bool(self._inflight)  # (before the proof lets the program send more)
        if self.capabilities.ok_means == "received":
            self._complete_runs(self._proofs.idle(self._acked_through))
        if unanswered and self._hold is None and self._probes_outstanding == 0:
            self._probe()

    def _complete_runs(self, lines: list[_Line]) -> None:
        """Lines acknowledged on receipt are now proven run: give their answers."""
        program_lines = 0
        for line in lines:
            assert line.receipt is not None
            program_lines += self._complete(line, line.receipt)
            if self._run_hold is line:
                self._run_hold = None
        self._count_program_lines(program_lines)
        self._pump()

    def _on_ok(self, ok: codec.Ok) -> None:
        self.capabilities.learn_ok(ok)
        plain = not ok.advanced and ok.temperatures is None and ok.position is None
        if self._resend_ok_due:
            self._resend_ok_due = False
            if plain:
                return  # the ok Marlin prints right after each Resend: line
        if self._skip_oks and plain and ok.line is None:
            self._skip_oks -= 1
            return  # the ok Repetier prints after each "skip N"
        if self._tail_oks and plain and ok.line is None:
            self._tail_oks -= 1
            if not self.capabilities.advanced_ok and self._hold is None:
                return  # (during the hold the resend's floor already keeps it from counting)
        if ok.advanced:
            if ok.line is not None:
                self._ack_through(ok.line, ok)
            else:
                self._ack_oldest(ok)  # an unnumbered command acknowledged in order
        elif ok.temperatures is not None or ok.position is not None:
            # The answer to M105 (or, on Smoothieware, M114), processed in order: every line
            # before the oldest unacknowledged such command has been processed too.
            word = "M105" if ok.temperatures is not None else "M114"
            query = next((line for line in self._history_from(self._acked_through + 1)
                          if _command_word(line.command) == word), None)
            if query is not None and self._dropped_before(query):
                return
            if query is not None:
                self._ack_through(query.number, ok)
                self._last_query = query.number
            else:
                self._ack_oldest(ok)
        elif self.capabilities.advanced_ok:
            return  # a plain ok from a firmware that acknowledges commands with P/B is no ack
        elif ok.line is not None:
            self._ack_through(ok.line, ok)
        else:
            self._ack_oldest(ok)
        self._pump()

    def _dropped_before(self, query: _Line) -> bool:
        """A query's answer came while a line before it is unacknowledged. Marlin's line numbers
        prove that line was processed (its ok was lost); a firmware that drops a line failing its
        checks without a word (RepRapFirmware 3) answers every other line with a plain ``ok``, so
        one of the lines since the last query it answered may never have run: stop, saying so."""
        oldest = self._acked_through + 1
        if self.capabilities.bad_lines != "discarded" or query.number <= oldest:
            return False
        since = self._last_query + 1
        self._fail(ProtocolError(
            f"printer answered line {query.number} ({query.command}) while line {oldest}{self._where(oldest)} "
            f"was unacknowledged: this firmware drops a line that fails its checks without a word, so one of "
            f"lines {since} to {query.number - 1} may never have run. Stopped with line {self._acked_through} "
            f"counted acknowledged; resume with the part reprinted"))
        return True

    def _ack_oldest(self, ok: codec.Ok) -> None:
        """A plain ok: the printer processes lines in number order, so it is the oldest's, except
        during a pending resend, where it acknowledges nothing at or above the line asked for:
        Marlin 2.x answers the tail of a line cut by its flush as an unnumbered command
        (``echo:Unknown command`` + ``ok``). A firmware with ADVANCED_OK numbers the ok of every
        numbered line, so there the resend stays pending until line N itself is acknowledged;
        without it, only while holding (its plain oks are the only acknowledgements)."""
        oldest = self._acked_through + 1
        floor = self._hold.target if self._hold is not None else None
        if self.capabilities.advanced_ok and self._pending_resend is not None:
            floor = self._pending_resend if floor is None else min(floor, self._pending_resend)
        if floor is not None and oldest >= floor:
            log.debug("unnumbered ok during the resend of line %d acknowledges nothing", floor)
            return
        self._ack_through(oldest, ok)

    def _ack_through(self, number: int, ok: codec.Ok) -> None:
        """Every line up to ``number`` has been processed, whether it is in flight or was taken out
        of flight by a resend request that needed no resend."""
        number = min(number, self._next_number - 1)
        if number <= self._acked_through or self._unproven_skipped(number, ok):
            return
        program_lines = 0
        received = self.capabilities.ok_means == "received"
        for n in range(self._acked_through + 1, number + 1):
            self._acked_through = n
            line = self._history.get(n)
            if line is None:
                continue
            if received:
                self._proofs.received(line, needs_proof=line.receipt is not None)
                if line.receipt is not None:
                    line.receipt = ok  # its answer waits for the proof that it ran
                    continue
            program_lines += self._complete(line, ok)
        while self._inflight and self._inflight[0].number <= number:
            self._inflight_bytes -= len(self._inflight.popleft().data)
        if self._nudge_behind is not None and self._nudge_behind <= number:
            self._nudge_behind = None  # read (and ignored) right after that line
        if self._asked_again:
            self._asked_again = {asked for asked in self._asked_again if asked > number}
        if self._solo is not None and self._solo <= number:
            self._solo = None  # the re-sent line acknowledged: the window opens again

        self._count_program_lines(program_lines)
        self._forget_old_history()

    def _complete(self, line: _Line, ok: codec.Ok) -> int:
        """Give ``line`` its answer; 1 when it is a program line (to count), else 0."""
        if line.future is not None and not line.future.done():
            line.future.set_result(Answer(line.command, line.number, line.events, ok))
        return 1 if line.program_index is not None else 0

    def _count_program_lines(self, count: int) -> None:
        if count and self._program is not None:
            self._program.acknowledged += count
            self._report_progress()
            self._maybe_finish_program()

    def _on_resend(self, number: int) -> None:
        refused, self._refused = self._refused, None
        if self.capabilities.ok_after_resend:
            self._resend_ok_due = True
        if number > self._next_number:
            self._fail(ProtocolError(f"printer asked to resend line {number}, which was never sent "
                                     f"(last line sent: {self._next_number - 1})"))
            return
        if number <= self._acked_through:
            self._fail(ProtocolError(
                f"printer asked to resend line {number}, which it had already acknowledged (up to "
                f"line {self._acked_through}): it has lost its state, probably a reset"))
            return
        if number < self._next_number and number not in self._history:
            self._fail(ProtocolError(f"printer asked to resend line {number}, which is no longer in "
                                     f"the history of {self._history_size} lines"))
            return
        self._note_asked_past(number)
        if self._solo is not None and number > self._solo:
            # Its line-number check refused the copy: the printer took the line in the first
            # pass, with the lines after it, whose oks the hold did not count (Marlin runs what
            # it takes; the silence probe's answer acknowledges them).
            self._solo = None
        if refused is not None and number > refused:
            # The request that answers an error asks past the line the error refused: the printer
            # marked that line received without running it.
            self._fail(ProtocolError(
                f"printer asked for line {number} after refusing line {refused}{self._where(refused)}, which "
                f"was not sent again: that line would never run. Stopped with every line before it "
                f"acknowledged (last line acknowledged: {self._acked_through}); resume from it"))
            return
        # Lines from `number` on are not in the printer: flushed with its receive buffer, or still
        # on the way, where each will be refused. They will be sent again.
        if self._nudge_behind is not None and self._nudge_behind >= number:
            self._nudge_behind = None  # flushed or read with them
        for line in self._inflight:
            if line.number >= number:
                self._inflight_bytes -= len(line.data)
                line.events.clear()
        self._inflight = deque(line for line in self._inflight if line.number < number)
        self._asked_again.add(number)
        if self._hold is None:
            self.resends += 1
            in_transit = self._inflight_bytes + sum(len(line.data) for line in self._history_from(number))
            hold = self.timeouts.resend_settle_s + (in_transit + codec.MAX_LINE_LENGTH) * self._byte_time
            timer = asyncio.get_running_loop().call_later(hold, self._end_hold)
            log.info("printer asked for line %d again; resending in at most %.0f ms", number, hold * 1000)
        elif number == self._hold.target:
            # A stale line refused: Marlin answers each line sent after the one asked for with
            # one request for it (unless its flush ate the line, then the timer ends the hold).
            self._hold.stale_seen += 1
            if self._hold.stale_seen >= self._hold.stale_expected:
                self._hold.timer.cancel()
                self._end_hold()
            return
        else:
            timer = self._hold.timer
        # A new target: every line transmitted after it is on its way and will draw a request
        # (the lines before it in flight are in the printer's queue and draw oks).
        self._hold = _Hold(timer, number, stale_expected=max(0, self._cursor - 1 - number))
        if self._hold.stale_expected == 0:
            timer.cancel()
            self._end_hold()

    @property
    def _pending_resend(self) -> int | None:
        """The lowest line asked for again and not yet acknowledged (a later request does not
        replace an earlier one: once the earlier line is acknowledged, the later one is pending)."""
        return min(self._asked_again) if self._asked_again else None

    def _where(self, number: int) -> str:
        """`` (program line K: COMMAND)`` for line ``number`` of the history, "" when unknown."""
        line = self._history.get(number)
        if line is None or line.program_index is None:
            return ""
        return f" (program line {line.program_index + 1}: {line.command})"

    def _note_asked_past(self, number: int) -> None:
        """The printer asks for ``number`` while the line it last asked for again, and was sent
        again, is still unacknowledged: it says it holds that line. Marlin does (the line waits in
        its queue and its ok follows), a firmware that swallowed the line never acknowledges it. With
        ADVANCED_OK every numbered line gets its own ``ok N<line>``, so from now on only that ok
        proves the line ran (see ``_ack_through``); plain oks carry no number to tell them apart."""
        pending = self._pending_resend
        if (self.capabilities.advanced_ok and self._hold is None and self._unproven is None
                and pending is not None and self._acked_through < pending < min(number, self._cursor)):
            self._unproven = pending

    def _unproven_skipped(self, number: int, ok: codec.Ok) -> bool:
        """Whether acknowledging through ``number`` would count the unproven line as done without
        its own ok: then the stream stops, naming it. Running it again is not safe (a move or an
        extrusion twice), so it is left to the resume, which starts from the line before it."""
        unproven = self._unproven
        if unproven is None or number < unproven:
            return False
        if ok.line == unproven:
            self._unproven = None  # its own ok: it ran
            return False
        self._fail(ProtocolError(
            f"printer acknowledged line {number} but never line {unproven}{self._where(unproven)}, which it had asked "
            f"for again, was sent again and then asked past: that line may never have run. Stopped "
            f"with every line before it acknowledged (last line acknowledged: {self._acked_through}); "
            f"resume from it"))
        return True

    def _on_line_error(self, error: codec.Error) -> None:
        """An error from the line checks names the last line the printer accepted: the line after
        it was refused, so the request that follows the error (Marlin prints both together) may not
        ask for a later one."""
        if error.kind not in (codec.ErrorKind.CHECKSUM, codec.ErrorKind.LINE_NUMBER,
                              codec.ErrorKind.NO_CHECKSUM, codec.ErrorKind.NO_LINE_NUMBER):
            return
        first = self._hold is None  # later errors of the episode come from the stale lines after it
        if error.last_line is None:
            if first:
                self.window.line_error(None)
            return
        refused = error.last_line + 1
        line = self._history.get(refused)
        if first:
            self.window.line_error(line.offset if line is not None else None)
        if refused <= self._acked_through or refused >= self._next_number:
            return  # already processed, or never sent: nothing can be skipped
        self._refused = refused

    def _history_from(self, number: int) -> list[_Line]:
        """The lines from ``number`` up to the last one numbered, oldest first."""
        return [self._history[n] for n in range(number, self._next_number) if n in self._history]

    def _end_hold(self) -> None:
        """Every byte sent before the request has reached the printer: resend, once. (Called by the
        hold's timer or once its episode is complete; ``stop`` cancels the timer and drops the hold,
        so a failed sender never gets here.)"""
        hold, self._hold = self._hold, None
        if hold is None:
            return
        # Lines acknowledged meanwhile (a request that came without a flush) need not go again:
        # acknowledgements counted by line number never run ahead of what the printer processed.
        target = max(hold.target, min(self._acked_through + 1, self._next_number))
        self._cursor = target
        if self._plain_ok and target < self._next_number:
            self._send_alone(target)
        self._pump()
        self._maybe_finish_program()

    # ------------------------------------------------------------------ re-sent lines, plain ok

    @property
    def _plain_ok(self) -> bool:
        """Whether acknowledgements name no line: a re-sent line's ``ok`` cannot be told from a
        later line's (firmware that checks line numbers and processes before its ``ok``)."""
        return (not self.capabilities.advanced_ok and self.capabilities.ok_means == "processed"
                and self.capabilities.bad_lines == "resend")

    def _send_alone(self, number: int) -> None:
        """Line ``number`` is sent again to plain-ok firmware: it goes alone, so that the next ``ok``
        is its own and, when none comes, the printer's position tells whether it ran (a firmware
        that times out after a resend request marks the re-sent line received without running it,
        and its later lines' plain oks would count it as done)."""
        self._solo = number

    def _give_back_numbers_after(self, number: int) -> None:
        """The lines numbered after the silent re-sent line ``number`` are not in the printer (it
        asked for ``number``, and answered none of them): they give their numbers back and go again
        after the proof, which takes the numbers right after ``number``."""
        program = self._program
        for n in range(self._next_number - 1, number, -1):
            line = self._history.pop(n, None)
            if line is None:
                continue
            if line.program_index is not None and program is not None:
                program.next_index = min(program.next_index, line.program_index)
            elif line.future is not None:
                self._singles.appendleft(_Fresh(line.command, line.future))  # numbered afresh
            # (a probe or a follow-up query: made again if still needed)
        self._next_number = self._cursor = number + 1

    def _on_resent_silence(self, silent: float) -> None:
        """The re-sent line drew no ``ok`` in its time: prove by the position that it ran, or stop."""
        assert self._solo is not None
        line = self._history.get(self._solo)
        where = self._where(self._solo)
        if self._resent_proof is not None:
            self._fail(ProtocolError(
                f"no answer for {silent:.1f} s to M400 + M114 sent to prove that line {self._solo}{where} ran "
                f"(the printer had asked for it again, and gave no ok when it was sent again). Stopped with "
                f"line {self._acked_through} the last acknowledged; resume from the line after it"))
            return
        program = self._program
        expected = None
        if line is not None and line.program_index is not None and program is not None:
            expected = expected_position(program.commands, line.program_index)
        if line is None or expected is None or any(queued.number > self._solo for queued in self._inflight):
            self._fail(ProtocolError(
                f"printer gave no ok for line {self._solo}{where}, which it had asked for again and was sent "
                f"again: that line may never have run (a firmware that times out after a resend request marks "
                f"it received without running it), and it is not a move whose position proves it ran. Stopped "
                f"with line {self._acked_through} the last acknowledged; resume from the line after it"))
            return
        log.warning("no ok for re-sent line %d; proving it ran with M400 + M114", self._solo)
        self._give_back_numbers_after(self._solo)
        for command in ("M400", "M114"):
            query = _Line(self._next_number, command, codec.encode(self._next_number, command))
            self._history[query.number] = query
            self._next_number += 1
            self._cursor += 1
            self._transmit(query)
        self._resent_proof = _ResentProof(line, self._next_number - 1, expected)
        self._last_heard = time.monotonic()

    def _on_proof_event(self, event: codec.Event) -> bool:
        """An event while a re-sent line's proof is out; True when it is the proof's own. Its oks
        (the M400's and M114's, and a late one of the line) acknowledge nothing: the report decides,
        once the M114's ok is in too (before or after the report: ``Capabilities.position_report``)."""
        proof = self._resent_proof
        assert proof is not None
        if isinstance(event, codec.Resend):
            self._fail(ProtocolError(
                f"printer asked for line {event.line} while M400 + M114 were proving that line "
                f"{proof.line.number}{self._where(proof.line.number)} ran: stopped with line "
                f"{self._acked_through} the last acknowledged; resume from the line after it"))
            return True
        if isinstance(event, codec.Position):
            proof.report = event
            if self.capabilities.position_report == "after_ok":
                self._conclude_proof(proof)
            return True  # the proof's own: not output of the command before the silent line
        if not isinstance(event, codec.Ok):
            return False
        if event.position is not None:
            proof.report = event.position
        if proof.report is not None:
            self._conclude_proof(proof)
        return True

    def _conclude_proof(self, proof: _ResentProof) -> None:
        report = proof.report
        assert report is not None
        self._resent_proof = None
        number = proof.line.number
        if at_position((report.x, report.y, report.z), proof.expected):
            log.info("re-sent line %d proven run by the position (%s)", number, proof.expected)
            self._ack_through(proof.query, codec.Ok())
            self._pump()
            return
        found = ", ".join(f"{axis}{value:g}" for axis, value in zip("XYZ", (report.x, report.y, report.z)))
        wanted = ", ".join(f"{axis}{value:g}" for axis, value in proof.expected.items())
        self._fail(ProtocolError(
            f"line {number}{self._where(number)} never ran: the printer had asked for it again, gave no ok "
            f"when it was sent again, and after M400 it is at {found}, not at {wanted} where that line "
            f"leaves the program. Stopped with line {self._acked_through} the last acknowledged; resume "
            f"from the line after it"))

    # ------------------------------------------------------------------ transmitting

    def _window_allows(self, size: int) -> bool:
        if not self._inflight:
            return True
        if self.ping_pong:
            return False
        # Every line in flight is in the printer's queue or on its way to a free slot of it: a line
        # left waiting in the receive buffer could be cut in two by the flush after an error.
        if len(self._inflight) >= self.capabilities.queue_slots:
            return False
        # a nudge's newline still in the receive buffer takes a byte of it
        nudge = 1 if self._nudge_behind is not None else 0
        return self._inflight_bytes + nudge + size <= self.window.window

    def _next_fresh(self) -> _Fresh | None:
        """The next command not yet numbered: a single (from ``send`` or a follow-up) first."""
        if self._singles:
            return self._singles[0]
        program = self._program
        if program is None or program.paused or program.cancelled:
            return None
        if program.next_index >= len(program.commands):
            return None
        index = program.next_index
        if index in program.barriers and program.acknowledged < index:
            return None
        if self._run_hold is not None:
            return None  # a program M400 acknowledged on receipt: its run is not proven yet
        return _Fresh(program.commands[index], program_index=index)

    def _pump(self) -> None:
        if self._failure is not None or self._hold is not None:
            return
        while True:
            if self._solo is not None and self._cursor > self._solo:
                return  # a re-sent line goes alone until its ok, or its proof, comes
            if self._cursor < self._next_number:
                line = self._history[self._cursor]
            else:
                fresh = self._next_fresh()
                if fresh is None:
                    return
                data = codec.encode(self._next_number, fresh.command)
                if not self._window_allows(len(data)):
                    return
                single = fresh.program_index is None
                if single:
                    self._singles.popleft()
                else:
                    assert self._program is not None
                    self._program.next_index += 1
                line = _Line(self._next_number, fresh.command, data, fresh.program_index, future=fresh.future)
                self._history[line.number] = line
                self._next_number += 1
                self._follow_up(line, single)
            if not self._window_allows(len(line.data)):
                return
            self._transmit(line)
            self._cursor += 1

    def _follow_up(self, line: _Line, single: bool) -> None:
        """A query sent right behind ``line`` where the firmware's ``ok`` alone does not prove it.

        Where ``ok`` means "received": a command whose answer must mean "it has run" (every command
        from ``send``, a program's ``M400``) is followed by an ``M114``, whose report proves it; a
        program waits for its ``M400``'s proof before its next line. Where a bad line is dropped
        without a word: an ``M400`` (a part's end, the end of a job) is followed by an ``M105``,
        whose ``ok T:…`` names its line, so a line dropped before it is found before the ``M400``
        counts (``_dropped_before``)."""
        word = _command_word(line.command)
        if self.capabilities.ok_means == "received":
            if single and word not in _ANSWERED_ON_RECEIPT or not single and word == "M400":
                line.receipt = codec.Ok()  # placeholder until its own ok arrives
                self._singles.appendleft(_Fresh("M114"))
                if not single:
                    self._run_hold = line
        elif self.capabilities.bad_lines == "discarded" and word == "M400":
            self._singles.appendleft(_Fresh(PROBE_COMMAND))

    def _transmit(self, line: _Line) -> None:
        if not self._inflight:
            self._last_heard = time.monotonic()  # the silence clock starts with the first line out
        self._inflight.append(line)
        self._inflight_bytes += len(line.data)
        line.offset = self._inflight_bytes
        self.window.line_sent(line.offset)
        self._write(line.data)

    def _forget_old_history(self) -> None:
        oldest_kept = self._acked_through + 1 - self._history_size
        while self._history_floor < oldest_kept:
            self._history.pop(self._history_floor, None)
            self._history_floor += 1

    # ------------------------------------------------------------------ program bookkeeping

    def _report_progress(self) -> None:
        program = self._program
        if program is None or program.progress is None:
            return
        program.progress(StreamProgress(
            total=len(program.commands),
            sent=program.next_index,
            acknowledged=program.acknowledged,
            resends=self.resends,
            elapsed_s=time.monotonic() - program.started,
        ))

    def _maybe_finish_program(self) -> None:
        program = self._program
        if program is None:
            return
        outstanding = any(line.program_index is not None
                          for line in self._history_from(self._acked_through + 1))
        if program.cancelled and not outstanding:
            self._program = None
            self._run_hold = None  # its M400's proof may still come; nothing waits for it now
            if not program.done.done():
                program.done.set_exception(StreamCancelled(
                    f"cancelled after {program.acknowledged} of {len(program.commands)} lines"))
            return
        if program.acknowledged >= len(program.commands) and not outstanding:
            self._finish_program()

    def _finish_program(self) -> None:
        program = self._program
        if program is None:
            return
        self._program = None
        if not program.done.done():
            program.done.set_result(StreamResult(
                lines=len(program.commands),
                resends=self.resends,
                elapsed_s=time.monotonic() - program.started,
                probes=self.probes,
                window_bytes=self.window.window,
                window_verdict=self.window.verdict.value,
                nudges=self.nudges,
            ))

    # ------------------------------------------------------------------ silence

    async def _watch(self) -> None:
        # look often enough to nudge on time; the probe's timeouts are seconds
        nudge = self.timeouts.nudge_s
        tick = min(0.05, nudge / 3) if nudge > 0 else 0.05
        while self._failure is None:
            await asyncio.sleep(tick)
            if not self._inflight:
                continue
            limit = self.timeouts.for_command(self._inflight[0].command)
            if limit is None:
                continue
            silent = time.monotonic() - self._last_heard
            if self._hold is not None:
                continue
            if limit == self.timeouts.default_s:
                # (not behind a heating wait, homing or a dwell: silence is expected there, and the
                # newlines would pile up in a receive buffer the firmware is not reading)
                self._maybe_nudge(silent)
            if silent < limit:
                continue
            if self._solo is not None:
                self._on_resent_silence(silent)
                continue
            if self._probes_outstanding >= self.timeouts.probes:
                oldest = self._inflight[0]
                self._fail(PrinterSilent(
                    f"no answer from the printer for {silent:.1f} s while line {oldest.number} "
                    f"({oldest.command}) was unacknowledged, after {self._probes_outstanding} probes"))
                return
            self._probe()

    def _maybe_nudge(self, silent: float) -> None:
        nudge = self.timeouts.nudge_s
        if nudge <= 0 or silent < nudge or self._nudged_at == self._last_heard:
            return
        if self.capabilities.answers_empty_line:
            return  # Smoothieware answers an empty line with ok: that ok would acknowledge a line
        self._nudged_at = self._last_heard
        self.nudges += 1
        self._nudge_behind = self._cursor - 1
        self._write(b"\n")

    def _probe(self) -> None:
        """Send a numbered M105 regardless of the window: its answer settles what happened."""
        self._probes_outstanding += 1
        self.probes += 1
        self._last_heard = time.monotonic()
        line = _Line(self._next_number, PROBE_COMMAND, codec.encode(self._next_number, PROBE_COMMAND))
        log.info("printer silent; probing with line %d", line.number)
        if self._cursor < self._next_number:
            # Rewound lines are waiting: they go first and the probe follows them, whatever the
            # window says (after this silence its count of bytes in flight is not to be trusted).
            self._history[line.number] = line
            self._next_number += 1
            if self._hold is None:
                while self._cursor < self._next_number:
                    self._transmit(self._history[self._cursor])
                    self._cursor += 1
            return
        self._history[line.number] = line
        self._next_number += 1
        self._cursor += 1
        self._transmit(line)

    # ------------------------------------------------------------------ failure

    def _fail(self, reason: LinkError) -> None:
        log.error("%s", reason)
        self.stop(reason)

    def _raise_if_failed(self) -> None:
        if self._failure is not None:
            raise self._failure
