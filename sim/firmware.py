"""Marlin 2.x's serial intake, command queue and command handlers, and other firmwares' answers.

Everything runs in virtual time: the caller hands over bytes with their arrival time
and asks the firmware to ``advance`` to a time; the firmware processes planner
completions, waits and periodic reports in time order.  Output goes through the
``emit`` callback with the time the line was printed.

Command life cycle, as in Marlin's queue.cpp / gcode.cpp:
  receive buffer -> (line checks) -> command queue (``bufsize`` slots) -> handler
  -> ``ok`` once the handler returns (a move: once its block is in the planner).
Handlers that must wait are generators yielding wait conditions; the queue slot
stays taken and ``echo:busy:`` keepalives are printed meanwhile.

With a dialect (``SimConfig.dialect``, ``dialects.py``) the board answers as that firmware does:
its banner, ``M115``, report formats, ``ok`` forms and timing (Repetier acknowledges a line on
receipt), line checks and resend requests (Smoothieware's ``rs N``, Repetier's ``skip``,
RepRapFirmware dropping a bad line), busy and ``wait`` lines, and what a halt leaves.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from .config import SimConfig
from .dialects import DIALECTS, MARLIN_SETTINGS, REPETIER_BUSY, position_report, temperature_report
from .emergency import EmergencyParser
from .faults import FaultInjector
from .frame import Frame
from .gcode import GCode, checksum, parse, strip_line_number, strtol
from .planner import Block, Planner, Position
from .record import CommandRecord, Recorder, Segment
from .stats import Stats
from .thermal import Heater

__all__ = ["Firmware", "Emit", "FIRMWARE_NAME", "MACHINE_UUID"]

FIRMWARE_NAME = "Marlin 2.1.2.1 (sim)"  # the historical board's (dialects.STOCK)
MACHINE_UUID = "cede2a2f-41a2-4748-9b12-c55c62f367ff"
WAIT_AFTER_S = 1.0  # Repetier prints "wait" after this long with an empty buffer (gcode.cpp)
# Smoothieware keeps answering these while halted (GcodeDispatch.cpp allowed_mcodes)
SMOOTHIE_HALTED_MCODES = {"M2", "M5", "M9", "M30", "M105", "M114", "M115", "M119", "M80", "M81", "M911",
                          "M503", "M106", "M107"}
MAX_CMD_SIZE = 96  # Marlin's line buffer: at most 95 characters are kept
DEFAULT_FEED = 1500.0  # mm/min, Marlin's power-on feed rate
HOMING_S = 3.0
STEPS_PER_MM = (80.0, 80.0, 400.0, 93.0)
MAX_HOTEND_C = 275.0
MAX_BED_C = 120.0
HEAT_REPORT_S = 1.0  # M109/M190 print a temperature line this often (wall)

ERR_KILLED = "Error:Printer halted. kill() called!"  # Marlin's; each dialect's lines: dialects.py
ERR_LINE_NO = "Line Number is not Last Line Number+1, Last Line: "
ERR_CHECKSUM = "checksum mismatch, Last Line: "
ERR_NO_CHECKSUM = "No Checksum with line number, Last Line: "
ERR_NO_LINE_NUMBER = "No Line Number with checksum, Last Line: "
_N_DIGITS = re.compile(r"N([-+0-9]*)")


def _word(text: str) -> str:
    """The command word of a received line (``N12 m110 N12*34`` -> ``M110``)."""
    words = strip_line_number(text).upper().split()
    return words[0] if words else ""


# emit(text, time, is_ok): print one line (without newline) at virtual time ``time``.
Emit = Callable[[str, float, bool], None]


@dataclass
class QueuedCommand:
    text: str
    """The stored line, leading spaces skipped, still with N<line> and *checksum."""
    line: int | None
    n_text: str | None
    """The digits after a leading N, echoed verbatim by ADVANCED_OK."""
    skip_ok: bool = False


# --- wait conditions yielded by blocking handlers -------------------------------------

class _Cond:
    busy = "processing"

    def check(self, fw: Firmware) -> bool:
        raise NotImplementedError

    def wake(self, fw: Firmware) -> float | None:
        return None


class _PlannerSpace(_Cond):
    def check(self, fw: Firmware) -> bool:
        return fw.planner.moves_free() > 0

    def wake(self, fw: Firmware) -> float | None:
        return fw.planner.next_completion()


class _PlannerEmpty(_Cond):
    def check(self, fw: Firmware) -> bool:
        return fw.planner.is_empty()

    def wake(self, fw: Firmware) -> float | None:
        return fw.planner.next_completion()


class _Until(_Cond):
    def __init__(self, t: float) -> None:
        self.t = t

    def check(self, fw: Firmware) -> bool:
        return fw.t >= self.t

    def wake(self, fw: Firmware) -> float | None:
        return self.t


class _UserWait(_Cond):
    busy = "paused for user"

    def __init__(self, deadline: float | None) -> None:
        self.deadline = deadline

    def check(self, fw: Firmware) -> bool:
        return not fw.wait_for_user or (self.deadline is not None and fw.t >= self.deadline)

    def wake(self, fw: Firmware) -> float | None:
        return self.deadline


class _HeatWait(_Cond):
    busy = "heating"

    def __init__(self, heater: Heater, wait_cooling: bool, t: float) -> None:
        self.heater = heater
        self.wait_cooling = wait_cooling
        self.next_report = t  # Marlin prints the first line right away

    def check(self, fw: Firmware) -> bool:
        fw.update_thermal()
        if not fw.wait_for_heatup or self.heater.reached(self.wait_cooling):
            return True
        if fw.t >= self.next_report:
            report = fw.heating_report(self.heater)
            if report:
                fw.emit(report)
            self.next_report = fw.t + HEAT_REPORT_S
        return False

    def wake(self, fw: Firmware) -> float | None:
        h = self.heater
        if h.temp < h.target - 1.0:
            reach = h.time_to_reach()
        elif h.target > 0:
            reach = h.time_to_cool(h.target + 1.0)
        else:
            reach = h.time_to_cool(30.0)
        return min(self.next_report, fw.t + reach * fw.config.time_scale)


@dataclass
class _Running:
    cmd: QueuedCommand
    gen: Iterator[_Cond]
    cond: _Cond | None = None


Handler = Callable[["Firmware", GCode, QueuedCommand], "Iterator[_Cond] | None"]


class Firmware:
    """One simulated Marlin board.  Not thread-safe: drive it from a single thread."""

    def __init__(self, config: SimConfig, *, emit: Emit, recorder: Recorder, stats: Stats,
                 frame: Frame, faults: FaultInjector,
                 on_trigger: Callable[[str], None] = lambda name: None,
                 on_reset: Callable[[], None] = lambda: None) -> None:
        self.config = config
        self.spec = config.spec  # the firmware's answers (dialects.py)
        self._out = emit
        self.recorder = recorder
        self.stats = stats
        self.frame = frame
        self.faults = faults
        self._on_trigger = on_trigger
        self._on_reset = on_reset
        self.t = 0.0
        self.planner = Planner(config.planner_blocks)
        self.hotend = Heater("T", tau_s=15.0, max_c=MAX_HOTEND_C)
        self.bed = Heater("B", tau_s=45.0, max_c=MAX_BED_C)
        self._thermal_t = 0.0
        self._ep = EmergencyParser()
        self.rx = bytearray()
        self._lb = bytearray()
        self._lb_skip = False
        self._flush_until: float | None = None  # bytes arriving by then go with the last flush
        self._swallow: int | None = None  # swallow_resent: the line to take silently when re-sent
        self._lose_next = False  # swallow_resent: the line after the swallowed one is lost
        self._ignore: int | None = None  # ignore_resent: the line to mark received when re-sent
        self._last_rx = 0.0  # when bytes last arrived (Repetier's "wait" counts from it)
        self._next_wait = 0.0
        self._waiting_resend = -1  # Repetier: stale lines still to skip after a resend request
        self.queue: deque[QueuedCommand] = deque()
        self._current: _Running | None = None
        self.halted_at: float | None = None
        self.booting_until: float | None = None
        self._last_motion_end: float | None = None
        self._synced = True
        self._init_state()

    # --- state -----------------------------------------------------------------------

    def _init_state(self) -> None:
        """Power-on state of everything a reset loses."""
        self.last_n = 0
        self.halted = False
        self.halted_at = None
        self.position: Position = (0.0, 0.0, 0.0, 0.0)
        self.relative_xyz = False
        self.relative_e = False
        self.feed = DEFAULT_FEED
        self.feed_percent = 100.0  # M220: every G0/G1 runs at feed × this / 100
        self.flow_percent = 100.0  # M221: every move's filament is E × this / 100
        self.fan = 0
        self.autoreport_s: float | None = None
        self._next_autoreport = 0.0
        self.busy: str | None = None
        self._next_busy = 0.0
        self.wait_for_user = False
        self.wait_for_heatup = False
        self.fatal_line: str | None = None  # Repetier's fatal state: its message, repeated
        self.update_thermal()  # the lazy model needs the old target up to now
        self.hotend.target = 0.0
        self.bed.target = 0.0

    def reset(self, t: float, *, count: bool = True, keep_output: bool = False) -> None:
        """Reboot: all state is lost, the banner follows after ``boot_s``; ``keep_output``: the
        lines printed just before still go out (a firmware that reboots itself after saying why)."""
        self._set_time(t)
        self._stop_motion()
        self._drop_queue()
        self._init_state()
        self._last_motion_end = None
        self._synced = True
        self.planner.clear()
        self._ep.reset()
        self.faults.reset_line_state()
        self.booting_until = self.t + self.config.boot_s
        if count:
            self.stats.resets += 1
        if not keep_output:
            self._on_reset()

    def reset_stats(self) -> None:
        # The first block after a stats reset must not count as a starvation.
        self._last_motion_end = None

    def _drop_queue(self) -> None:
        if self._current is not None:
            self._current.gen.close()
            self._current = None
        self.queue.clear()
        self.busy = None
        self.rx.clear()
        self._lb.clear()
        self._lb_skip = False
        self._flush_until = None
        self._swallow = None
        self._lose_next = False
        self._ignore = None

    def _stop_motion(self) -> None:
        partial = self.planner.quickstop(self.t)
        if partial is not None:
            self._block_done(partial)
        # Marlin takes the position back from the steppers after a quick stop.
        self.position = self.planner.position_at(self.t)

    def _set_time(self, t: float) -> None:
        if t > self.t:
            self.t = t

    def update_thermal(self) -> None:
        dt = self.t - self._thermal_t
        if dt > 0:
            phys = dt / self.config.time_scale
            self.hotend.advance(phys)
            self.bed.advance(phys)
            self._thermal_t = self.t

    # --- output ----------------------------------------------------------------------

    def emit(self, text: str, ok: bool = False) -> None:
        self._out(text, self.t, ok)

    def temperature_report(self) -> str:
        """The temperatures as this firmware reports them (``M105`` without ``ok``, ``M155``)."""
        self.update_thermal()
        h, b = self.hotend, self.bed
        return temperature_report(self.spec, (h.temp, h.target, h.power), (b.temp, b.target, b.power))

    def heating_report(self, heater: Heater) -> str:
        """The line a heating wait prints every second ("" where the firmware prints none)."""
        name = self.spec.name
        if name == "reprapfirmware":
            return ""  # RepRapFirmware reports nothing on the serial line while it waits
        if name == "smoothieware":
            # TemperatureControl.cpp on_second_tick(): "%s:%3.1f /%3.1f @%d" for the heater waited on
            self.update_thermal()
            return f"{heater.name}:{heater.temp:.1f} /{heater.target:.1f} @{heater.power}"
        if name == "repetier":
            return self.temperature_report()
        return " " + self.temperature_report() + " W:?"  # Marlin's print_heater_states + " W:?"

    def busy_line(self, reason: str) -> str:
        """A keepalive line for a command that blocks ("" where the firmware prints none)."""
        if not self.spec.busy:
            return ""
        if self.spec.name == "repetier":
            return self.spec.busy.format(reason=REPETIER_BUSY.get(reason, reason))
        # Marlin and Prusa have no "heating" keepalive: a heating wait reports "processing"
        return self.spec.busy.format(reason="processing" if reason == "heating" else reason)

    def _banner(self) -> None:
        for text in self.spec.banner:
            self.emit(text.format(planner_bytes=88 * self.config.planner_blocks))

    # --- time ------------------------------------------------------------------------

    def advance(self, t: float) -> None:
        """Let time run to ``t``: boot, planner completions, waits and reports, in order."""
        if self.booting_until is not None:
            if t < self.booting_until:
                self._set_time(t)
                return
            self._set_time(self.booting_until)
            self.booting_until = None
            self._banner()
        while True:
            end = self.planner.next_completion()
            if end is None or end > t:
                break
            self._set_time(end)
            self._block_done(self.planner.complete_head())
            self._service()
        self._set_time(t)
        self._periodic()
        self._service()

    def next_event(self) -> float | None:
        """When ``advance`` next has something to do (None: only input can wake it)."""
        if self.booting_until is not None:
            return self.booting_until
        times = [self.planner.next_completion()]
        if self._current is not None and self._current.cond is not None:
            times.append(self._current.cond.wake(self))
        if self.busy is not None and self.config.keepalive_s > 0:
            times.append(self._next_busy)
        if self.autoreport_s is not None:
            times.append(self._next_autoreport)
        if self.spec.says_wait:
            times.append(max(self._last_rx + WAIT_AFTER_S, self._next_wait))
        if self._current is None and self.queue and not self.halted:
            times.append(self.t)
        valid = [x for x in times if x is not None]
        return min(valid) if valid else None

    def is_idle(self) -> bool:
        """Nothing queued, running or planned, and no complete line waiting."""
        return (self.booting_until is None and self._current is None and not self.queue
                and self.planner.is_empty() and b"\n" not in self.rx and b"\r" not in self.rx)

    def _periodic(self) -> None:
        if self.busy is not None and self.config.keepalive_s > 0 and self.t >= self._next_busy:
            line = self.busy_line(self.busy)
            if line:
                self.emit(line)
                self.stats.busy_lines += 1
            self._next_busy = self.t + self.config.keepalive_s
        if self.autoreport_s is not None and self.t >= self._next_autoreport:
            # Marlin's autoreport starts with a space (print_heater_state); Repetier's does not
            lead = "" if self.spec.name == "repetier" else " "
            self.emit(lead + self.temperature_report())
            self._next_autoreport = max(self._next_autoreport + self.autoreport_s,
                                        self.t + 0.5 * self.autoreport_s)
        if self._wait_due():
            self.emit("wait")
            self._next_wait = self.t + WAIT_AFTER_S

    def _wait_due(self) -> bool:
        """Repetier's readFromSerial(): "wait" once a second while nothing is buffered or arrives."""
        return (self.spec.says_wait and not self.queue and self._current is None and not self.halted
                and self.booting_until is None and not self.rx
                and self.t >= max(self._last_rx + WAIT_AFTER_S, self._next_wait))

    # --- serial receive --------------------------------------------------------------

    def receive(self, data: bytes, t: float) -> None:
        """Bytes that arrived on the wire by time ``t`` (normally up to one newline)."""
        self._set_time(t)
        self._last_rx = t
        if self.booting_until is not None:
            self.stats.boot_lost_bytes += len(data)
            return
        if self.spec.name == "smoothieware" and b"\x18" in data:
            # SerialConsole.cpp: Ctrl-X halts at once and flushes what the buffer holds
            data = data[data.rindex(b"\x18") + 1:]
            self.rx.clear()
            self._lb.clear()
            self.halt(("HALTED, M999 or $X to exit HALT state",))
        emergencies = self._ep.feed(data) if self.spec.emergency_parser else []
        if self._flush_until is not None:
            # Bytes that arrived before the main loop came back to the buffer were flushed.
            if t <= self._flush_until:
                lost = len(data)
            else:
                lost = max(0, len(data) - int((t - self._flush_until) / self.config.byte_time) - 1)
                self._flush_until = None
            data = data[lost:]
        self._into_rx(data)
        for code in emergencies:
            self._emergency(code)
        self._service()

    def _into_rx(self, data: bytes) -> None:
        cap = self.config.rx_buffer
        pos = 0
        while pos < len(data):
            space = cap - len(self.rx)
            if space <= 0:
                # The main loop may free room by moving lines to the queue.
                self._service()
                space = cap - len(self.rx)
                if space <= 0 or self.booting_until is not None:
                    break
            chunk = data[pos:pos + space]
            self.rx += chunk
            pos += len(chunk)
        if pos < len(data):
            self.stats.dropped_bytes += len(data) - pos
        if len(self.rx) > self.stats.rx_peak:
            self.stats.rx_peak = len(self.rx)

    def _emergency(self, code: str) -> None:
        if code == "M112":
            self.halt(self.spec.stop_lines, reboot=self.spec.halt == "reboot")
        elif code == "M108":
            self.wait_for_user = False
            self.wait_for_heatup = False
        elif code == "M410" and not self.halted:
            self._stop_motion()

    def halt(self, lines: tuple[str, ...] | None = None, *, reboot: bool = False) -> None:
        """kill(): print ``lines`` (the dialect's emergency stop lines by default), stop
        everything, and stay halted, answering every later line as the firmware does, until M999
        or a reset; ``reboot``: the board restarts instead (Prusa's kill(), Repetier's
        KILL_METHOD 1)."""
        if self.halted:
            return
        for line in self.spec.stop_lines if lines is None else lines:
            self.emit(line)
        if reboot:
            self.stats.halts += 1
            self.reset(self.t, count=False, keep_output=True)
            return
        if self.spec.name == "repetier" and lines:
            self.fatal_line = lines[0]  # gcode.cpp reportFatalError(), for every later line
        self.halted = True
        self.halted_at = self.t
        self.stats.halts += 1
        self._stop_motion()
        self._drop_queue()
        self._synced = True
        self.update_thermal()
        self.hotend.target = self.bed.target = 0.0
        self.autoreport_s = None
        self.wait_for_user = self.wait_for_heatup = False

    def thermal_error(self, kind: str) -> None:
        """A thermal runaway ("runaway") or a broken thermistor ("mintemp"): the dialect's lines,
        then halted."""
        self.halt(self.spec.runaway_lines if kind == "runaway" else self.spec.mintemp_lines)

    # --- the main loop: intake and processing ---------------------------------------

    def _service(self) -> None:
        if self.booting_until is not None:
            return
        while True:
            progressed = self._intake()
            progressed = self._process() or progressed
            if not progressed or self.booting_until is not None:
                return

    def _intake(self) -> bool:
        """get_serial_commands(): move complete lines into the queue while it has room."""
        progressed = False
        if self.config.blocking_intake and self._current is not None:
            return False  # the main loop is inside the blocked handler
        while len(self.queue) < self.config.bufsize and self.rx and self.booting_until is None:
            i = self.rx.find(b"\n")
            j = self.rx.find(b"\r")
            eol = i if j < 0 else (j if i < 0 else min(i, j))
            progressed = True
            if eol < 0:
                # Marlin reads a partial line into its line buffer right away.
                self._line_add(self.rx)
                self.rx.clear()
                break
            self._line_add(self.rx[:eol])
            del self.rx[:eol + 1]
            line = bytes(self._lb)
            self._lb.clear()
            self._lb_skip = False
            self._handle_line(line)
        return progressed

    def _line_add(self, data: bytes | bytearray) -> None:
        if self._lb_skip:
            return
        k = data.find(b";")
        if k >= 0:  # an end-of-line comment is never stored
            data = data[:k]
            self._lb_skip = True
        room = MAX_CMD_SIZE - 1 - len(self._lb)
        if len(data) > room:  # overflow: the rest of the line is ignored
            data = data[:room]
            self._lb_skip = True
        self._lb += data

    def _handle_line(self, raw: bytes) -> None:
        """A complete line: the dialect's checks, then enqueue."""
        cmd_b = raw.lstrip(b" ")
        if not cmd_b.strip():
            if self.spec.answers_empty_line:
                self.emit("ok", True)  # GcodeDispatch.cpp: "just reply ok to empty lines"
            return
        self.stats.lines_received += 1
        text = cmd_b.decode("latin-1")
        checks = self.spec.line_checks
        if checks == "smoothie":
            self._smoothie_line(cmd_b, text)
        elif checks == "repetier":
            self._repetier_line(cmd_b, text)
        elif checks == "rrf":
            self._rrf_line(cmd_b, text)
        elif self.halted:
            if _word(text) == "M999":
                self.reset(self.t)
            else:
                self.emit(self.spec.halted_answer)
        else:
            self._marlin_line(cmd_b, text)
        if len(self.queue) > self.stats.queue_peak:
            self.stats.queue_peak = len(self.queue)

    def _marlin_line(self, cmd_b: bytes, text: str) -> None:
        """The checks of Marlin's queue.cpp, then enqueue."""
        line: int | None = None
        n_text: str | None = None
        if text[0] == "N":
            m110 = "M110" in text
            npos = 0
            if m110:
                n2 = text.find("N", 4)
                if n2 >= 0:
                    npos = n2
            number = strtol(text, npos + 1)
            if number != self.last_n + 1 and not m110:
                self.stats.line_number_errors += 1
                self._line_error(ERR_LINE_NO)
                return
            star = cmd_b.rfind(b"*")
            if star < 0:
                self.stats.checksum_errors += 1
                self._line_error(ERR_NO_CHECKSUM)
                return
            if strtol(text, star + 1) != checksum(cmd_b[:star]):
                self.stats.checksum_errors += 1
                if self.faults.config.skip_refused:
                    # A buggy firmware: the refused line is marked received (never run), so the
                    # request that follows asks for the line after it.
                    self.emit(f"Error:{ERR_CHECKSUM}{self.last_n}")
                    self.last_n = number
                    self.rx.clear()
                    self._lb.clear()
                    self._lb_skip = False
                    self.stats.skipped_lines += 1
                    self._request_resend()
                    return
                self._line_error(ERR_CHECKSUM)
                return
            if self._swallow_resent(number) or self._ignore_resent(number):
                return
            self.last_n = number
            m = _N_DIGITS.match(text)
            n_text = m.group(1) if m else ""
            line = strtol(text, 1)
            self.queue.append(QueuedCommand(text, line, n_text))
            self._after_numbered_line()
        elif b"*" in cmd_b and self.config.cut_tail == "reject":
            # Marlin 1.x: "No '*' without 'N'". A line cut by a receive-buffer flush arrives as its
            # tail, with the checksum but without the number: it must never run unchecked.
            # Marlin 2.x (cut_tail "marlin2") has no such check: the tail is queued as an
            # unnumbered command, answered `echo:Unknown command` + `ok` (or run, if it parses).
            self.stats.checksum_errors += 1
            self._line_error(ERR_NO_LINE_NUMBER)
            return
        else:
            if b"*" in cmd_b:
                self.stats.cut_tails_queued += 1
            self.queue.append(QueuedCommand(text, None, None))

    def _checksum_ok(self, cmd_b: bytes, text: str, required: bool) -> bool:
        """Whether a numbered line's ``*checksum`` matches (a line without one: ``not required``)."""
        star = cmd_b.rfind(b"*")
        if star < 0:
            return not required
        return strtol(text, star + 1) == checksum(cmd_b[:star])

    def _smoothie_line(self, cmd_b: bytes, text: str) -> None:
        """Smoothieware's GcodeDispatch.cpp: a numbered line with a wrong checksum or number is
        answered ``rs N<expected>`` (nothing is flushed; no ok); M110 sets the number; while halted,
        every command but a few queries is answered ``!!``, and M999 leaves the halt."""
        number: int | None = None
        if text[0] == "N":
            number = strtol(text, 1)
            if _word(text) == "M110":
                self.last_n = number
                self.emit("ok", True)
                return
            good = self._checksum_ok(cmd_b, text, required=False)
            if not good or number != self.last_n + 1:
                if good:
                    self.stats.line_number_errors += 1
                else:
                    self.stats.checksum_errors += 1
                self._request_resend()
                return
            self.last_n = number
        if self.halted:
            word = _word(text)
            if word == "M999":
                self.halted = False
                self.halted_at = None
                self.emit("WARNING: After HALT you should HOME as position is currently unknown")
                self.emit("ok", True)
                return
            if word not in SMOOTHIE_HALTED_MCODES:
                self.emit("!!")
                return
        self.queue.append(QueuedCommand(text, number, None))
        if number is not None:
            self._after_numbered_line()

    def _repetier_line(self, cmd_b: bytes, text: str) -> None:
        """Repetier's gcode.cpp: a wrong checksum asks for the line again (flush, ``Resend:N``, ok);
        a line it has already seen, or one of the stale lines after a request, is answered ``skip N``
        and ok; another wrong number asks again; a good line is acknowledged on receipt
        (``ok N``); in the fatal state every line gets the fatal message before its ok."""
        number: int | None = None
        word = _word(text)
        if text[0] == "N":
            number = strtol(text, 1)
            if not self._checksum_ok(cmd_b, text, required=False):
                self.stats.checksum_errors += 1
                self.emit("Error:Wrong checksum")
                self._flush_and_resend()
                return
            if word == "M110":
                self.last_n = number
                self._waiting_resend = -1
                self.emit("ok", True)
                return
            if (number & 0xFFFF) != ((self.last_n + 1) & 0xFFFF):
                self._repetier_out_of_order(number)
                return
            self.last_n = number
        if self.fatal_line is not None and word == "M999":
            self.fatal_line = None  # gcode.cpp resetFatalError(), printed when it runs
            self.halted, self.halted_at = False, None
            self.emit(f"ok {number}" if number is not None else "ok", True)
            self.emit("info:Continue from fatal state")
        else:
            if self.fatal_line is not None:
                self.emit(self.fatal_line)  # reportFatalError(): not queued, still acknowledged
            else:
                self.queue.append(QueuedCommand(text, number, None, skip_ok=True))
            self.emit(f"ok {number}" if number is not None else "ok", True)
        self._waiting_resend = -1
        if number is not None:
            self._after_numbered_line()

    def _repetier_out_of_order(self, number: int) -> None:
        if ((self.last_n - number) & 0xFFFF) < 40 or self._waiting_resend >= 0:
            if ((self.last_n - number) & 0xFFFF) >= 40:
                self._waiting_resend -= 1  # a stale line after a request: skipped without a word
            self.emit(f"skip {number}")
            self.emit("ok", True)
            return
        self.stats.line_number_errors += 1
        self.emit(f"Error:expected line {self.last_n + 1} got {number}")
        self._flush_and_resend()

    def _flush_and_resend(self) -> None:
        """Repetier's requestResend(): the receive buffer flushed, then the request."""
        self.rx.clear()
        self._lb.clear()
        self._lb_skip = False
        self._request_resend()

    def _rrf_line(self, cmd_b: bytes, text: str) -> None:
        """RepRapFirmware 3's StringParser.cpp LineFinished(): a line whose checksum is wrong is
        dropped without a word; line numbers are not checked; after an emergency stop only M999
        (a reset) is taken."""
        if not self._checksum_ok(cmd_b, text, required=False):
            self.stats.checksum_errors += 1
            self.stats.skipped_lines += 1
            return
        if self.halted:
            if _word(text) == "M999":
                self.reset(self.t)
            return
        number = strtol(text, 1) if text[0] == "N" else None
        if number is not None:
            self.last_n = number
        self.queue.append(QueuedCommand(text, number, None))
        if number is not None:
            self._after_numbered_line()

    def _swallow_resent(self, number: int) -> bool:
        """The swallow_resent fault on a numbered line that passed the checks: True when the line
        was taken by it (refused as corrupted, swallowed, or lost)."""
        if self._lose_next:
            self._lose_next = False  # lost with the swallowed line: no answer, number not kept
            return True
        if self._swallow == number:
            self._swallow = None
            self.last_n = number  # marked received, never queued, never answered
            self.stats.swallowed_line = number
            self._lose_next = True
            return True
        if self.faults.swallow_due():
            self._swallow = number
            self.stats.checksum_errors += 1
            self._line_error(ERR_CHECKSUM)
            return True
        return False

    def _ignore_resent(self, number: int) -> bool:
        """The ignore_resent fault on a numbered line that passed the checks: True when the line
        was taken by it (refused as corrupted, or marked received without running or answering)."""
        if self._ignore == number:
            self._ignore = None
            self.last_n = number  # the next line expected is number + 1; this one never runs
            self.stats.ignored_resent_line = number
            return True
        if self.faults.ignore_due():
            self._ignore = number
            self.stats.checksum_errors += 1
            self._line_error(ERR_CHECKSUM)
            return True
        return False

    def _after_numbered_line(self) -> None:
        if self.faults.spurious_resend():
            self.stats.spurious_resends += 1
            self._request_resend()
        for name in self.faults.line_accepted():
            if name == "reset":
                self.reset(self.t)
            elif name in ("runaway", "mintemp"):
                self.thermal_error(name)
            else:
                self._on_trigger(name)

    def _line_error(self, message: str) -> None:
        """gcode_line_error(): report, discard the receive buffer, ask for a resend."""
        self.emit(f"Error:{message}{self.last_n}")
        if self.config.read_latency_s > 0:
            self._flush_until = self.t + self.config.read_latency_s
        self.rx.clear()
        self._lb.clear()
        self._lb_skip = False
        self._request_resend()

    def _request_resend(self) -> None:
        """Ask for the line after the last one taken, in the dialect's words."""
        if not self.spec.resend:
            return  # RepRapFirmware 3 never asks
        if self.spec.line_checks == "repetier":
            self._waiting_resend = 14  # requestResend(): the stale lines that follow are skipped
            self.emit("")  # Com::println() before the request
        self.emit(self.spec.resend.format(n=self.last_n + 1))
        self.stats.resends_requested += 1
        if self.config.ok_after_resend:
            self.emit("ok", True)

    def _process(self) -> bool:
        """Run the head of the queue, or see whether the blocked handler may go on."""
        if self.halted and not self._runs_while_halted():
            return False
        running = self._current
        if running is not None:
            if running.cond is None or not running.cond.check(self):
                return False
            self._resume(running)
            return True
        if not self.queue:
            return False
        cmd = self.queue[0]
        command = strip_line_number(cmd.text)
        self.recorder.add_command(CommandRecord(cmd.line, command, self.t))
        self.stats.commands_executed += 1
        gen = self._execute(cmd, command)
        if gen is None:
            self._finish(cmd)
        else:
            running = _Running(cmd, gen)
            self._current = running
            self._resume(running)
        return True

    def _runs_while_halted(self) -> bool:
        """Smoothieware keeps answering its queries while halted (GcodeDispatch.cpp allowed_mcodes)."""
        return (self.spec.name == "smoothieware" and self._current is None and bool(self.queue)
                and _word(self.queue[0].text) in SMOOTHIE_HALTED_MCODES)

    def _resume(self, running: _Running) -> None:
        while True:
            try:
                cond = next(running.gen)
            except StopIteration:
                self._current = None
                self.busy = None
                self._finish(running.cmd)
                return
            if self._current is not running:  # the handler halted or reset the board
                return
            if not cond.check(self):
                running.cond = cond
                if self.busy is None or self.busy != cond.busy:
                    # Marlin re-arms the keepalive timer whenever it was not busy.
                    self.busy = cond.busy
                    self._next_busy = self.t + self.config.keepalive_s
                return

    def _finish(self, cmd: QueuedCommand) -> None:
        """ok_to_send(), then free the slot (Repetier acknowledged the line on receipt)."""
        if not cmd.skip_ok:
            self._emit_ok(cmd)
        if self.queue and self.queue[0] is cmd:
            self.queue.popleft()

    def _emit_ok(self, cmd: QueuedCommand) -> None:
        if self.config.advanced_ok:
            n = f" N{cmd.n_text}" if cmd.n_text is not None else ""
            self.emit(f"ok{n} P{self.planner.moves_free()} B{self.config.bufsize - len(self.queue)}", True)
        else:
            self.emit("ok", True)

    def _ok_first(self, cmd: QueuedCommand) -> None:
        """``ok_before_output``: the command's ok now, before its output, and none when it ends."""
        if self.config.ok_before_output and not cmd.skip_ok:
            self._emit_ok(cmd)
            cmd.skip_ok = True

    # --- motion ----------------------------------------------------------------------

    def _block_done(self, block: Block) -> None:
        self._last_motion_end = block.t_end
        x0, y0, _, e0 = block.start
        x1, y1, z1, e1 = block.end
        de = e1 - e0
        if de > 0 and (x1 != x0 or y1 != y0):
            (fx0, fy0), (fx1, fy1) = self.frame.to_fabric([(x0, y0), (x1, y1)]).tolist()
            self.recorder.add_segment(Segment(
                x0, y0, x1, y1, z1, de, block.feed, block.t_end, self.frame.side,
                fx0, fy0, fx1, fy1))
            self.stats.segments += 1
            self.stats.extruded_mm += de

    def _plan(self, start: Position, end: Position, duration: float, feed: float) -> Iterator[_Cond]:
        if self.planner.moves_free() <= 0:
            yield _PlannerSpace()
            self.position = end  # an M410 meanwhile reset it; the move still goes to its target
        if self.planner.is_empty() and self._last_motion_end is not None and not self._synced:
            self.stats.starvations += 1
            self.stats.starved_s += max(0.0, self.t - self._last_motion_end)
        self._synced = False
        self.planner.add(start, end, feed, duration, self.t)
        if len(self.planner) > self.stats.planner_peak:
            self.stats.planner_peak = len(self.planner)

    def _sync(self) -> Iterator[_Cond]:
        """planner.synchronize(): wait for every move to finish."""
        self._synced = True
        yield _PlannerEmpty()
        self._synced = True

    def _physical(self, seconds: float) -> float:
        """Wall seconds a physical duration takes."""
        return seconds * self.config.time_scale

    # --- handlers ----------------------------------------------------------------------

    def _execute(self, cmd: QueuedCommand, command: str) -> Iterator[_Cond] | None:
        g = parse(command)
        handler = _HANDLERS.get(g.code) if g is not None else None
        if g is not None and g.code == "M155" and not self.spec.m155:
            handler = None
        if g is None or handler is None:
            if self.spec.unknown:
                word = command.split()[0] if command.split() else command
                text = command if "{command}" in self.spec.unknown and self.spec.name != "reprapfirmware" else word
                self.emit(self.spec.unknown.format(command=text))
            return None
        return handler(self, g, cmd)

    def _g0_g1(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond] | None:
        old = self.position
        new = list(old)
        for i, axis in enumerate("XYZ"):
            v = g.value(axis)
            if v is not None:
                new[i] = old[i] + v if self.relative_xyz else v
        v = g.value("E")
        if v is not None:
            new[3] = old[3] + v if self.relative_e else v
        f = g.value("F")
        if f is not None and f > 0:
            self.feed = f
        end: Position = (new[0], new[1], new[2], new[3])
        self.position = end
        dist = ((new[0] - old[0]) ** 2 + (new[1] - old[1]) ** 2 + (new[2] - old[2]) ** 2) ** 0.5
        length = dist if dist > 0 else abs(new[3] - old[3])
        if length == 0:
            return None  # Marlin drops zero-length moves
        # M220 scales the feed, M221 the filament pushed (the E position stays the commanded one,
        # as Marlin's current_position does; only the steps the extruder makes are scaled)
        feed = self.feed if self.feed_percent == 100.0 else self.feed * self.feed_percent / 100.0
        e = new[3] if self.flow_percent == 100.0 else old[3] + (new[3] - old[3]) * self.flow_percent / 100.0
        pushed: Position = (new[0], new[1], new[2], e)
        return self._plan(old, pushed, self._physical(length / feed * 60.0), feed)

    def _g4(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond]:
        seconds = (g.value("P", 0.0) or 0.0) / 1000.0
        if g.has("S"):
            seconds = g.value("S", 0.0) or 0.0
        yield from self._sync()
        yield _Until(self.t + self._physical(seconds))

    def _g28(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond]:
        yield from self._sync()
        yield _Until(self.t + self._physical(HOMING_S))
        axes = [i for i, a in enumerate("XYZ") if g.has(a)] or [0, 1, 2]
        pos = list(self.position)
        for i in axes:
            pos[i] = 0.0
        self.position = (pos[0], pos[1], pos[2], pos[3])
        self.planner.set_position(self.position)
        self._synced = True

    def _g90(self, g: GCode, cmd: QueuedCommand) -> None:
        self.relative_xyz = self.relative_e = False

    def _g91(self, g: GCode, cmd: QueuedCommand) -> None:
        self.relative_xyz = self.relative_e = True

    def _g92(self, g: GCode, cmd: QueuedCommand) -> None:
        pos = list(self.position)
        for i, axis in enumerate("XYZE"):
            v = g.value(axis)
            if v is not None:
                pos[i] = v
        self.position = (pos[0], pos[1], pos[2], pos[3])
        if self.planner.is_empty():
            self.planner.set_position(self.position)

    def _m0_m1(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond]:
        yield from self._sync()
        seconds: float | None = None
        if g.has("P"):
            seconds = (g.value("P", 0.0) or 0.0) / 1000.0
        if g.has("S"):
            seconds = g.value("S", 0.0) or 0.0
        deadline = None if not seconds else self.t + self._physical(seconds)
        self.wait_for_user = True
        yield _UserWait(deadline)
        self.wait_for_user = False
        self._synced = True

    def _m82(self, g: GCode, cmd: QueuedCommand) -> None:
        self.relative_e = False

    def _m83(self, g: GCode, cmd: QueuedCommand) -> None:
        self.relative_e = True

    def _set_target(self, heater: Heater, g: GCode) -> bool:
        """Apply S (or R); False if no temperature was given or it was refused."""
        value = g.value("S") if g.has("S") else g.value("R")
        if value is None:
            return False
        if value > heater.max_c:
            kind = "Hotend" if heater is self.hotend else "Bed"
            self.emit(f"echo:{kind} target {value:.0f} exceeds maximum {heater.max_c:.0f}; ignored")
            return False
        self.update_thermal()
        heater.target = max(0.0, value)
        return True

    def _m104(self, g: GCode, cmd: QueuedCommand) -> None:
        self._set_target(self.hotend, g)

    def _m140(self, g: GCode, cmd: QueuedCommand) -> None:
        self._set_target(self.bed, g)

    def _heat_and_wait(self, heater: Heater, g: GCode) -> Iterator[_Cond]:
        self._synced = True  # a heating wait is a pause the host asked for
        if not self._set_target(heater, g):
            return
        self.wait_for_heatup = True
        yield _HeatWait(heater, wait_cooling=not g.has("S"), t=self.t)
        self.wait_for_heatup = False
        self._synced = True

    def _m109(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond]:
        return self._heat_and_wait(self.hotend, g)

    def _m190(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond]:
        return self._heat_and_wait(self.bed, g)

    def _m105(self, g: GCode, cmd: QueuedCommand) -> None:
        if self.spec.ok_on_receipt:
            self.emit(self.temperature_report())  # Repetier: its ok came on receipt
            return
        # Marlin's M105 prints its own ok, never with ADVANCED_OK's N/P/B fields (so do
        # RepRapFirmware's, "ok " + the reply, and Smoothieware's, "ok " + txt_after_ok).
        cmd.skip_ok = True
        self.emit("ok " + self.temperature_report(), True)

    def _m106(self, g: GCode, cmd: QueuedCommand) -> None:
        self.fan = int(max(0.0, min(255.0, g.value("S", 255.0) or 0.0)))

    def _m107(self, g: GCode, cmd: QueuedCommand) -> None:
        self.fan = 0

    def _m110(self, g: GCode, cmd: QueuedCommand) -> None:
        # As Marlin: the line number is set again when M110 runs, not only on intake.
        n = g.value("N")
        if n is not None:
            self.last_n = int(n)

    def _m114(self, g: GCode, cmd: QueuedCommand) -> None:
        sx, sy, sz, _ = STEPS_PER_MM
        ax, ay, az, _ = self.planner.position_at(self.t)
        counts = (round(ax * sx), round(ay * sy), round(az * sz))
        if self.config.m114_on_ok:
            # Smoothieware: the position is the text after "ok" (GcodeDispatch prints "ok %s" with
            # the gcode's txt_after_ok; Robot::print_position writes "C: X:%1.4f Y:%1.4f Z:%1.4f").
            cmd.skip_ok = True
            self.emit("ok " + position_report(DIALECTS["smoothieware"], self.position, counts), True)
            return
        self._ok_first(cmd)
        self.emit(position_report(self.spec, self.position, counts))

    def _m115(self, g: GCode, cmd: QueuedCommand) -> None:
        self._ok_first(cmd)
        for line in self.spec.m115:
            self.emit(line)

    def _m112(self, g: GCode, cmd: QueuedCommand) -> None:
        """M112 from the queue (firmware without an emergency parser: it waited its turn). No ok
        follows (Smoothieware's stop line is its ok: "ok Emergency Stop Requested - …")."""
        cmd.skip_ok = True
        self.halt(self.spec.stop_lines, reboot=self.spec.halt == "reboot")

    def _m118(self, g: GCode, cmd: QueuedCommand) -> None:
        text = strip_line_number(cmd.text)[4:].strip()
        prefix = ""
        if text[:2] in ("E1", "A1") and (len(text) == 2 or text[2] == " "):
            prefix = "echo:" if text[0] == "E" else "//"
            text = text[2:].strip()
        self.emit(prefix + text)

    def _m155(self, g: GCode, cmd: QueuedCommand) -> None:
        s = g.value("S")
        if s is None:
            return
        if s <= 0:
            self.autoreport_s = None
        else:
            self.autoreport_s = max(0.1, s)
            self._next_autoreport = self.t + self.autoreport_s

    def _m400(self, g: GCode, cmd: QueuedCommand) -> Iterator[_Cond]:
        return self._sync()

    def _m502(self, g: GCode, cmd: QueuedCommand) -> None:
        self.emit("echo:Hardcoded Default Settings Loaded")

    def _m503(self, g: GCode, cmd: QueuedCommand) -> None:
        for text in MARLIN_SETTINGS:
            self.emit(text)

    def _m220(self, g: GCode, cmd: QueuedCommand) -> None:
        # Marlin's M220.cpp: S sets feedrate_percentage; without words it reports "FR:<n>%"
        s = g.value("S")
        if s is not None:
            self.feed_percent = float(max(10, min(999, round(s))))  # Marlin keeps an int, 10-999
        elif not g.params:
            self.emit(f"FR:{self.feed_percent:.0f}%")

    def _m221(self, g: GCode, cmd: QueuedCommand) -> None:
        # Marlin's M221.cpp: S sets the flow percentage of the extruder (T, default 0); without S it
        # reports "echo:E0 Flow: <n>%"
        s = g.value("S")
        if s is not None:
            self.flow_percent = float(max(10, min(999, round(s))))
        else:
            self.emit(f"echo:E0 Flow: {self.flow_percent:.0f}%")

    def _t(self, g: GCode, cmd: QueuedCommand) -> None:
        n = int(g.code[1:])
        if n != 0:
            self.emit(f"echo:T{n} Invalid extruder")

    def _nothing(self, g: GCode, cmd: QueuedCommand) -> None:
        """Known commands with no simulated effect (M108/M112/M410 ran at arrival)."""


_HANDLERS: dict[str, Handler] = {
    "G0": Firmware._g0_g1, "G1": Firmware._g0_g1, "G4": Firmware._g4,
    "G28": Firmware._g28, "G90": Firmware._g90, "G91": Firmware._g91, "G92": Firmware._g92,
    "M0": Firmware._m0_m1, "M1": Firmware._m0_m1,
    "M82": Firmware._m82, "M83": Firmware._m83,
    "M104": Firmware._m104, "M105": Firmware._m105, "M106": Firmware._m106,
    "M107": Firmware._m107, "M109": Firmware._m109, "M110": Firmware._m110,
    "M112": Firmware._m112, "M114": Firmware._m114, "M115": Firmware._m115, "M118": Firmware._m118,
    "M140": Firmware._m140, "M155": Firmware._m155, "M190": Firmware._m190,
    "M220": Firmware._m220, "M221": Firmware._m221, "M400": Firmware._m400, "M502": Firmware._m502, "M503": Firmware._m503,
    "T0": Firmware._t, "T1": Firmware._t, "T2": Firmware._t, "T3": Firmware._t,
}
for _code in ("M17", "M18", "M84", "M31", "M73", "M75", "M76", "M77", "M92", "M108",
              "M117", "M201", "M203", "M204", "M205", "M410",
              "M999"):
    _HANDLERS[_code] = Firmware._nothing
