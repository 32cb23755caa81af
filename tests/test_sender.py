"""The sender on scripted printer answers: each scenario is what Marlin prints in that situation."""

from __future__ import annotations

import asyncio
import re

import pytest

from ribbond.printer import codec
from ribbond.printer.capabilities import Capabilities
from ribbond.printer.errors import PrinterSilent, ProtocolError, StreamCancelled
from ribbond.printer.sender import Sender, Timeouts

LINE = re.compile(rb"^N(\d+) (.*)\*(\d+)\n$")


class Wire:
    """Collects what the sender writes, as (line number, command)."""

    def __init__(self) -> None:
        self.lines: list[tuple[int, str]] = []
        self.nudges = 0

    def write(self, data: bytes) -> None:
        if data == b"\n":
            self.nudges += 1
            return
        match = LINE.match(data)
        assert match, data
        self.lines.append((int(match.group(1)), match.group(2).decode()))

    def numbers(self) -> list[int]:
        return [n for n, _ in self.lines]


def make(advanced: bool = False, rx: int = 127, **kwargs) -> tuple[Sender, Wire]:
    wire = Wire()
    caps = Capabilities(rx_buffer_bytes=rx)
    sender = Sender(wire.write, caps, **kwargs)
    return sender, wire


def feed(sender: Sender, *lines: str) -> None:
    for line in lines:
        sender.handle(codec.parse_line(line))


async def ack_numbered_from(sender: Sender, done: asyncio.Future, line: int, pause: float = 0.005) -> None:
    """Answer ``ok N<line> P15 B3``, ``ok N<line+1> …`` until the stream ends (ADVANCED_OK)."""
    while not done.done():
        feed(sender, f"ok N{line} P15 B3")
        line += 1
        await asyncio.sleep(pause)


def program(n: int) -> list[str]:
    return [f"G1 X{i % 100}.5 Y{i % 37}.25 F3000" for i in range(n)]


async def test_window_is_bounded_by_receive_buffer_bytes() -> None:
    sender, wire = make(rx=127)
    done = sender.stream(program(20))
    sizes = [len(codec.encode(n, c)) for n, c in wire.lines]
    assert sum(sizes) <= 127
    assert sum(sizes) + len(codec.encode(len(wire.lines), program(20)[len(wire.lines)])) > 127
    done.cancel()


async def test_ping_pong_keeps_one_line_in_flight() -> None:
    sender, wire = make(ping_pong=True)
    done = sender.stream(program(3))
    assert wire.numbers() == [0]
    feed(sender, "ok")
    assert wire.numbers() == [0, 1]
    feed(sender, "ok", "ok")
    result = await asyncio.wait_for(done, 1)
    assert result.lines == 3


async def test_window_is_bounded_by_the_queue_slots() -> None:
    sender, wire = make(rx=4096)
    done = sender.stream(program(40))
    assert len(wire.lines) == 4, "Marlin's default BUFSIZE until the printer says otherwise"
    # An ADVANCED_OK acknowledgement reporting 7 free slots shows a queue of at least 8.
    feed(sender, "ok N0 P15 B7")
    assert sender.capabilities.queue_slots == 8
    assert sender.in_flight == 8
    done.cancel()


SETTLE = Timeouts(resend_settle_s=0.01)


async def test_resend_goes_out_once_every_stale_line_has_drawn_its_request() -> None:
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(10))
    feed(sender, "ok")  # line 0 processed; the window moves on
    first_window = wire.numbers()
    assert first_window[0] == 0 and len(first_window) >= 4
    # Line 1 arrived corrupted: Marlin flushes its buffer and asks for 1 (then a plain ok). The
    # other lines of the window still reach its parser and are refused the same way, one request
    # each: while one may still come, nothing goes out.
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    for _ in first_window[2:-1]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    assert wire.numbers() == first_window, "nothing goes out while stale requests may still come"
    # The last line sent has drawn its request: nothing stale is left on the wire, so the resend
    # starts at once (the settle time of 10 s is not waited for), from the line asked for.
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    assert wire.numbers()[len(first_window)] == 1
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0)
    result = done.result()
    assert result.lines == 10 and result.resends == 1
    sent = wire.numbers()
    assert sorted(set(sent)) == list(range(10))
    assert all(sent.count(n) == 2 for n in first_window[1:]), "the refused lines went out again, once"
    assert all(sent.count(n) == 1 for n in range(10) if n == 0 or n not in first_window)


async def test_lines_flushed_silently_leave_the_hold_to_the_timer() -> None:
    """Marlin's flush may eat stale lines without a reply: fewer requests than lines sent after
    the one asked for, so only the wire time (plus the settle margin) ends the hold."""
    sender, wire = make(rx=127, timeouts=SETTLE)
    done = sender.stream(program(10))
    feed(sender, "ok")
    first_window = wire.numbers()
    assert len(first_window) >= 4
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    await asyncio.sleep(0)
    assert wire.numbers() == first_window, "a stale line may still be on its way"
    await asyncio.sleep(0.1)  # settle 10 ms + wire time of < 250 bytes at 115200 baud (22 ms)
    assert wire.numbers()[len(first_window)] == 1
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0)
    assert done.result().lines == 10 and done.result().resends == 1


async def test_a_request_after_the_resend_is_honoured() -> None:
    """A flush caused by a stale line's tail can destroy the resent lines: asked again, sent again."""
    sender, wire = make(rx=127, timeouts=SETTLE)
    done = sender.stream(program(6))
    feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 0", "ok")
    await asyncio.sleep(0.05)
    resent = len(wire.lines)
    feed(sender, "Error:No Line Number with checksum, Last Line: -1", "Resend: 0", "ok")
    await asyncio.sleep(0.05)
    assert wire.numbers()[resent] == 0
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0)
    assert done.result().lines == 6


async def test_latest_request_wins_during_the_hold() -> None:
    sender, wire = make(rx=127, timeouts=SETTLE)
    done = sender.stream(program(8))
    feed(sender, "Resend: 0", "ok")  # spurious: the lines in its buffer are still accepted
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3", "ok N2 P15 B3")
    await asyncio.sleep(0.05)
    assert wire.numbers()[4] == 3, "with ADVANCED_OK the acknowledged lines are not sent again"
    done.cancel()


async def test_resend_of_an_acknowledged_line_means_the_printer_lost_its_state() -> None:
    sender, wire = make()
    done = sender.stream(program(10))
    feed(sender, "ok", "ok")  # lines 0 and 1 processed
    feed(sender, "Resend: 1")
    with pytest.raises(ProtocolError, match="already acknowledged"):
        await asyncio.wait_for(done, 1)


async def test_resend_of_a_line_never_sent_is_refused() -> None:
    sender, wire = make()
    done = sender.stream(program(10))
    feed(sender, "Resend: 50")
    with pytest.raises(ProtocolError, match="never sent"):
        await asyncio.wait_for(done, 1)


async def test_lost_ok_is_recovered_with_a_numbered_probe() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.2, probes=2))
    sender.start()
    done = sender.stream(program(2))
    assert wire.numbers() == [0]
    await asyncio.sleep(0.4)  # the ok for line 0 was lost
    assert wire.lines[-1] == (1, "M105")
    feed(sender, "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")  # the probe's answer: line 0 was done
    assert wire.lines[-1][1].startswith("G1")
    feed(sender, "ok")
    result = await asyncio.wait_for(done, 1)
    assert result.lines == 2 and result.probes == 1


async def test_probe_finds_a_lost_line() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.2, probes=2))
    sender.start()
    done = sender.stream(program(2))
    await asyncio.sleep(0.3)  # line 0 never reached the parser
    assert wire.lines[-1] == (1, "M105")
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: -1", "Resend: 0", "ok")
    await asyncio.sleep(0.1)  # the resend waits until stale requests can no longer come
    assert wire.lines[-1] == (0, program(2)[0])
    feed(sender, "ok", "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0", "ok")
    result = await asyncio.wait_for(done, 1)
    assert result.lines == 2


async def test_silent_printer_is_reported() -> None:
    sender, wire = make(timeouts=Timeouts(default_s=0.1, probes=2))
    sender.start()
    done = sender.stream(program(2))
    with pytest.raises(PrinterSilent, match="no answer"):
        await asyncio.wait_for(done, 2)


async def test_busy_keeps_a_command_alive() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.15, probes=1))
    sender.start()
    done = sender.send("G28")
    for _ in range(6):
        await asyncio.sleep(0.05)
        feed(sender, "echo:busy: processing")
    assert wire.numbers() == [0], "no probe while the printer says it is busy"
    feed(sender, "ok")
    await asyncio.wait_for(done, 1)


async def test_autoreports_do_not_hide_a_lost_ok() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.15, probes=2))
    sender.start()
    sender.stream(program(2))
    for _ in range(5):
        await asyncio.sleep(0.05)
        feed(sender, " T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")
    assert (1, "M105") in wire.lines


async def test_send_collects_the_answer_lines() -> None:
    sender, wire = make()
    future = sender.send("M115")
    feed(sender, "FIRMWARE_NAME:Marlin 2.1.2.1 (sim)", "Cap:AUTOREPORT_TEMP:1", "ok")
    answer = await asyncio.wait_for(future, 1)
    assert isinstance(answer.first(codec.FirmwareInfo), codec.FirmwareInfo)
    assert answer.line == 0


async def test_cancel_ends_after_lines_in_flight() -> None:
    sender, wire = make()
    done = sender.stream(program(50))
    in_flight = len(wire.lines)
    sender.cancel()
    for _ in range(in_flight):
        feed(sender, "ok")
    with pytest.raises(StreamCancelled, match=f"after {in_flight} of 50"):
        await asyncio.wait_for(done, 1)
    assert len(wire.lines) == in_flight


async def test_pause_stops_feeding_and_resume_goes_on() -> None:
    sender, wire = make(ping_pong=True)
    done = sender.stream(program(3))
    sender.pause()
    feed(sender, "ok")
    assert wire.numbers() == [0]
    sender.resume()
    assert wire.numbers() == [0, 1]
    feed(sender, "ok", "ok")
    await asyncio.wait_for(done, 1)


async def test_unnumbered_ok_during_a_resend_acknowledges_nothing_at_or_above_the_line_asked_for() -> None:
    """Marlin 2.x queues the tail of a line cut by its flush as an unnumbered command and answers
    it ``echo:Unknown command`` + an ok without N. That ok is not line N's: taking it so would make
    the printer's next request for N look like a reset."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(8))
    feed(sender, "ok N0 P15 B3")  # ADVANCED_OK learned; line 0 processed
    window = wire.numbers()
    assert len(window) >= 4
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    feed(sender, 'echo:Unknown command: "Y12.25 F3000*85"', "ok P15 B3")  # a cut tail
    assert sender.last_acknowledged_line == 0, "the tail's ok acknowledged line 1"
    for _ in window[2:]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    resent_from = len(window)
    assert wire.numbers()[resent_from] == 1
    feed(sender, 'echo:Unknown command: "5 F3000*85"', "ok P15 B3")  # a late tail, after the resend
    assert sender.last_acknowledged_line == 0, "the resend is pending until line 1 is acknowledged"
    await ack_numbered_from(sender, done, 1, pause=0)
    assert done.result().lines == 8


async def test_a_request_past_a_refused_line_is_a_protocol_error() -> None:
    """A printer that refuses line 2 and then asks for 3 marked 2 received without running it:
    streaming on would report success with line 2 missing."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    commands = program(8)
    done = sender.stream(commands)
    feed(sender, "ok", "ok")  # lines 0 and 1 processed
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 3", "ok")
    with pytest.raises(ProtocolError, match=rf"refusing line 2 \(program line 3: {commands[2]}\)"):
        await asyncio.wait_for(done, 1)
    assert sender.last_acknowledged_line == 1
    assert wire.numbers().count(2) == 1, "nothing went out after the error"


async def test_a_request_for_a_later_line_after_the_refused_one_was_resent_is_honoured() -> None:
    sender, wire = make(rx=127, timeouts=SETTLE)
    done = sender.stream(program(8))
    feed(sender, "ok")
    window = wire.numbers()
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    for _ in window[2:]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    assert wire.numbers()[len(window)] == 1, "line 1 went out again"
    # Line 1 accepted (in the queue), line 2 of the resend refused: a new request, no error.
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    await asyncio.sleep(0)
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0.01)
    assert done.result().lines == 8


def resend_episode(sender: Sender, wire: Wire, asked: int) -> None:
    """Line ``asked`` refused (checksum): the request, then one per stale line behind it, as Marlin
    with ADVANCED_OK prints them; the hold then ends and the lines go out again."""
    last = wire.numbers()[-1]
    feed(sender, f"Error:checksum mismatch, Last Line: {asked - 1}", f"Resend: {asked}", "ok")
    for _ in range(asked + 1, last + 1):
        feed(sender, f"Error:Line Number is not Last Line Number+1, Last Line: {asked - 1}",
             f"Resend: {asked}", "ok")


async def test_a_resent_line_asked_past_and_never_acknowledged_stops_the_stream() -> None:
    """Issue 22: the printer asks for 2 again, takes the re-sent 2 without a word, asks for 3, and
    acknowledges 3: 2 never ran. The stream stops naming it, with nothing from 2 on counted."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    commands = program(10)
    done = sender.stream(commands)
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3")
    resend_episode(sender, wire, 2)
    assert wire.numbers().count(2) == 2, "line 2 went out again"
    # 2 swallowed, 3 lost with it: the next line draws a request for 3
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3", "ok")
    await asyncio.sleep(0.01)
    feed(sender, "ok N3 P15 B3")
    with pytest.raises(ProtocolError, match=rf"acknowledged line 3 but never line 2 \(program line 3: "
                                            rf"{re.escape(commands[2])}\).*resume from it"):
        await asyncio.wait_for(done, 1)
    assert sender.last_acknowledged_line == 1


async def test_a_resent_line_acknowledged_after_a_request_past_it_counts() -> None:
    """Marlin's own order: the re-sent 2 waits in its queue, 3 is refused (a request for 3), then
    2's ok comes: nothing is missing and the stream goes on."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(10))
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3")
    resend_episode(sender, wire, 2)
    feed(sender, "Error:checksum mismatch, Last Line: 2", "Resend: 3", "ok")
    feed(sender, "ok N2 P15 B3")
    await asyncio.sleep(0.01)
    next_line = 3
    while not done.done():
        feed(sender, f"ok N{next_line} P15 B3")
        next_line += 1
        await asyncio.sleep(0.01)
    assert done.result().lines == 10


async def test_a_probe_answer_does_not_count_an_unproven_line() -> None:
    """The swallowed line's ok never comes: the silence probe's ``ok T:`` acknowledges everything
    before the probe, but not a line the printer claimed and never acknowledged."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10, default_s=0.1, nudge_s=0))
    sender.start()
    done = sender.stream(program(4))
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3")
    resend_episode(sender, wire, 2)
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3", "ok")
    await asyncio.sleep(0.01)
    deadline = asyncio.get_running_loop().time() + 2
    while not any(c == "M105" for _, c in wire.lines):
        assert asyncio.get_running_loop().time() < deadline, "no probe"
        await asyncio.sleep(0.02)
    feed(sender, "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")
    with pytest.raises(ProtocolError, match="never line 2"):
        await asyncio.wait_for(done, 1)
    assert sender.last_acknowledged_line == 1


async def test_a_silent_printer_is_nudged_with_one_bare_newline_per_silence() -> None:
    # Noise that turns a line's newline into another byte leaves the printer waiting for the rest
    # of that line: an empty line ends it (a checksum error follows) and is ignored otherwise.
    sender, wire = make(timeouts=Timeouts(nudge_s=0.1, default_s=5))
    sender.start()
    done = sender.stream(program(1))
    await asyncio.sleep(0.35)
    assert wire.nudges == 1, "once per silence, not every watchdog tick"
    feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 0", "ok")
    await asyncio.sleep(0.3)
    assert wire.numbers() == [0, 0], "the line whose newline was lost goes again"
    assert wire.nudges == 2, "the resent line met silence again: a new silence, a new nudge"
    feed(sender, "ok N0 P15 B3")
    assert (await asyncio.wait_for(done, 1)).lines == 1
    sender.stop(StreamCancelled("test over"))


async def test_a_nudge_takes_a_byte_of_the_window_until_the_line_before_it_is_acknowledged() -> None:
    # The newline waits in the receive buffer behind the last line sent: a window filled to the byte
    # would then overflow a buffer of exactly that size by one.
    moves = ["G1 X10 Y10 F3000", "G1 X20 Y10 F3000", "G1 X30 Y10 F3000"]
    sizes = [len(codec.encode(n, c)) for n, c in enumerate(moves)]
    assert sizes[0] == sizes[2], "the test needs line 2 to need exactly the room line 0 frees"
    sender, wire = make(rx=sizes[0] + sizes[1], timeouts=Timeouts(nudge_s=0.05, default_s=5))
    sender.start()
    done = sender.stream(moves)
    assert wire.numbers() == [0, 1]
    await asyncio.sleep(0.15)
    assert wire.nudges == 1
    feed(sender, "ok")
    assert wire.numbers() == [0, 1], "line 2 would overflow by the nudge's byte"
    feed(sender, "ok")
    assert wire.numbers() == [0, 1, 2], "read with line 1: its byte is free again"
    feed(sender, "ok")
    assert (await asyncio.wait_for(done, 1)).lines == 3
    sender.stop(StreamCancelled("test over"))


async def test_nudges_can_be_turned_off() -> None:
    sender, wire = make(timeouts=Timeouts(nudge_s=0, default_s=5))
    sender.start()
    done = sender.stream(program(1))
    await asyncio.sleep(0.3)
    assert wire.nudges == 0
    done.cancel()
    sender.stop(StreamCancelled("test over"))


def test_the_default_window_is_safe_for_a_64_byte_receive_buffer() -> None:
    assert Capabilities().rx_buffer_bytes == 63


async def test_no_nudge_behind_a_command_expected_to_be_silent() -> None:
    # Homing (or a heating wait, a dwell) is silent by nature, and the firmware reads no serial
    # meanwhile: newlines would only pile up in its receive buffer.
    sender, wire = make(timeouts=Timeouts(nudge_s=0.1, default_s=5))
    sender.start()
    done = sender.stream(["G28"])
    await asyncio.sleep(0.35)
    assert wire.nudges == 0
    feed(sender, "ok")
    assert (await asyncio.wait_for(done, 1)).lines == 1
    sender.stop(StreamCancelled("test over"))


# ---- issue 36: a re-sent line on plain-ok firmware is proven run, or the stream stops

def moves(n: int) -> list[str]:
    """Absolute moves, each 1 mm further along X than the one before (so each proves it ran)."""
    return ["G90"] + [f"G1 X{10 + i} Y5 F3000" for i in range(n)]


def plain_resend(sender: Sender, wire: Wire, asked: int) -> None:
    """Line ``asked`` refused (checksum) by plain-ok Marlin: the request and its ok, then one
    request per stale line behind it."""
    last = wire.numbers()[-1]
    feed(sender, f"Error:checksum mismatch, Last Line: {asked - 1}", f"Resend: {asked}", "ok")
    for _ in range(asked + 1, last + 1):
        feed(sender, f"Error:Line Number is not Last Line Number+1, Last Line: {asked - 1}",
             f"Resend: {asked}", "ok")


async def test_a_resent_line_goes_alone_until_its_ok_on_plain_ok_firmware() -> None:
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    commands = moves(8)
    done = sender.stream(commands)
    feed(sender, "ok", "ok")  # lines 0, 1
    plain_resend(sender, wire, 2)
    assert wire.numbers()[-1] == 2, "only the re-sent line is out"
    await asyncio.sleep(0.01)
    assert wire.numbers()[-1] == 2
    feed(sender, "ok")  # line 2's own ok: the window opens again
    assert wire.numbers()[-1] > 2
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0.01)
    assert done.result().lines == len(commands)
    resent = [i for i, (n, _) in enumerate(wire.lines) if n == 2][1]
    assert wire.lines[resent:] == list(enumerate(commands))[2:], "after it, every line once, in order"


async def proof_episode(order: str, report_x: float) -> tuple[Sender, Wire, asyncio.Future, list[str]]:
    """Line 2 (program line 3: G1 X11 Y5) asked for again, sent again, and then no ok: the sender
    proves it with M400 + M114; the printer answers with the report at ``report_x``, before its
    ``ok`` ("line", Marlin) or after it ("after_ok")."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10, default_s=0.1, nudge_s=0))
    sender.capabilities.position_report = order
    sender.start()
    commands = moves(8)
    done = sender.stream(commands)
    feed(sender, "ok", "ok")
    plain_resend(sender, wire, 2)
    deadline = asyncio.get_running_loop().time() + 2
    while wire.lines[-1][1] != "M114":
        assert asyncio.get_running_loop().time() < deadline, "no proof sent"
        await asyncio.sleep(0.02)
    assert wire.lines[-2:] == [(3, "M400"), (4, "M114")], "the proof goes right behind the silent line"
    report = f"X:{report_x:.2f} Y:5.00 Z:0.00 E:0.00 Count X:0 Y:0 Z:0"
    feed(sender, "ok", *((report, "ok") if order == "line" else ("ok", report)))
    return sender, wire, done, commands


@pytest.mark.parametrize("order", ["line", "after_ok"])
async def test_a_silent_resent_move_proven_by_the_position_counts_once(order: str) -> None:
    sender, wire, done, commands = await proof_episode(order, 11.0)  # where line 2 leaves the printer
    assert sender.last_acknowledged_line == 4
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0.01)
    assert done.result().lines == len(commands)
    resent = [i for i, (n, _) in enumerate(wire.lines) if n == 2][1]
    after = wire.lines[resent:]
    assert after[:3] == [(2, commands[2]), (3, "M400"), (4, "M114")]
    assert [c for _, c in after[3:]] == commands[3:], "then every later line once, in order"


@pytest.mark.parametrize("order", ["line", "after_ok"])
async def test_a_silent_resent_move_that_did_not_run_stops_the_stream_naming_it(order: str) -> None:
    sender, wire, done, commands = await proof_episode(order, 10.0)  # still where line 1 left it
    with pytest.raises(ProtocolError, match=rf"line 2 \(program line 3: {re.escape(commands[2])}\) never ran"):
        await asyncio.wait_for(done, 1)
    assert sender.last_acknowledged_line == 1
    assert wire.lines[-1] == (4, "M114"), "nothing after the proof went out"


async def test_a_silent_resent_line_that_is_not_a_move_stops_the_stream() -> None:
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10, default_s=0.1, nudge_s=0))
    sender.start()
    commands = ["G90", "G1 X10 Y5", "M104 S200", "G1 X11 Y5"]
    done = sender.stream(commands)
    feed(sender, "ok", "ok")
    plain_resend(sender, wire, 2)
    with pytest.raises(ProtocolError, match=r"no ok for line 2 \(program line 3: M104 S200\).*not a move"):
        await asyncio.wait_for(done, 2)
    assert "M114" not in [c for _, c in wire.lines] and sender.last_acknowledged_line == 1
