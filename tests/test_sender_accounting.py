"""The sender's accounting on scripted Marlin answers (issue 35, the mutation run's survivors): the
resend hold's length, the counts a stream reports (lines, resends, probes, nudges, the window), the
answers' acknowledgements, the byte window around acknowledgements and nudges, a probe behind
rewound lines, what the window governor is told, and a sender after ``stop`` or a line-number reset.
Expectations come from the protocol: 10 bits a byte on the wire (8N1), one request per stale line,
Marlin's numbered ``ok``."""

from __future__ import annotations

import asyncio

import pytest

from ribbond.printer import codec
from ribbond.printer.capabilities import Capabilities
from ribbond.printer.errors import LinkError, PrinterSilent, ProtocolError, StreamCancelled
from ribbond.printer.sender import Sender, Timeouts
from ribbond.printer.window import Verdict

from .test_sender import Wire, feed, make, program

#: Moves whose numbered lines (N0 to N5) all take 23 bytes, so one acknowledged frees one's room.
EQUAL = [f"G1 X{10 * (i + 1)} Y10 F3000" for i in range(6)]


def sizes(wire: Wire, numbers: range | list[int]) -> int:
    return sum(len(codec.encode(n, c)) for n, c in wire.lines if n in numbers)


async def wait_for_line(wire: Wire, command: str, count: int = 1, limit: float = 3.0) -> None:
    deadline = asyncio.get_running_loop().time() + limit
    while sum(c == command for _, c in wire.lines) < count:
        assert asyncio.get_running_loop().time() < deadline, f"no {command} sent"
        await asyncio.sleep(0.01)


async def test_the_resend_hold_is_the_wire_time_of_the_bytes_sent_plus_one_line(monkeypatch) -> None:
    """Every byte not yet acknowledged may still be on its way (the lines in the printer's queue and
    the stale ones after the line asked for), and one more line may be half read: at 10 bits a byte
    (8N1) at the default 115200 baud, plus the settle margin."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=0.02))
    loop = asyncio.get_running_loop()
    delays: list[float] = []
    real = loop.call_later

    def spy(delay, callback, *args, **kwargs):
        delays.append(delay)
        return real(delay, callback, *args, **kwargs)

    monkeypatch.setattr(loop, "call_later", spy)
    done = sender.stream(program(10))
    sent = wire.numbers()
    assert len(sent) >= 4
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2")  # lines 0 and 1 still in its queue
    wire_bits = (sizes(wire, sent) + codec.MAX_LINE_LENGTH) * 10
    assert delays == [pytest.approx(0.02 + wire_bits / 115200, rel=1e-12, abs=0)]
    done.cancel()
    sender.stop(StreamCancelled("test over"))


async def test_a_finished_stream_reports_its_counts_and_the_window() -> None:
    sender, wire = make(rx=127)
    done = sender.stream(program(3))
    feed(sender, "ok", "ok", "ok")
    result = await asyncio.wait_for(done, 1)
    assert (result.lines, result.resends, result.probes, result.nudges) == (3, 0, 0, 0)
    assert (result.window_bytes, result.window_verdict) == (127, "none")
    assert 0 <= result.elapsed_s < 5


async def test_the_result_carries_the_window_the_governor_left() -> None:
    """After a trial proved overflow the window is smaller than configured: the result says so."""
    sender, wire = make(rx=127)
    sender.window.verdict = Verdict.OVERFLOW
    sender.window.window = 63
    done = sender.stream(program(2))
    feed(sender, "ok", "ok")
    result = await asyncio.wait_for(done, 1)
    assert (result.window_bytes, result.window_verdict) == (63, "overflow")


async def test_progress_reports_total_sent_acknowledged_and_resends() -> None:
    seen = []
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(8), progress=seen.append)
    first = seen[-1]
    assert (first.total, first.sent, first.acknowledged, first.resends) == (8, 0, 0, 0)
    numbered = len(wire.lines)
    feed(sender, "ok")                               # told before the freed room is filled
    window = wire.numbers()
    now = seen[-1]
    assert (now.total, now.sent, now.acknowledged, now.resends) == (8, numbered, 1, 0)
    assert 0 <= now.elapsed_s < 5
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    for _ in window[2:]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    feed(sender, "ok")
    assert (seen[-1].acknowledged, seen[-1].resends) == (2, 1)
    done.cancel()


async def test_each_resend_episode_is_counted() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(3))
    for _ in range(2):  # line 0 refused twice; nothing stale behind it, so resent at once
        feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 0", "ok")
    assert wire.numbers() == [0, 0, 0]
    feed(sender, "ok", "ok", "ok")
    assert (await asyncio.wait_for(done, 1)).resends == 2


async def test_a_silent_printer_gets_the_probes_configured_then_is_reported() -> None:
    sender, wire = make(timeouts=Timeouts(default_s=0.1, probes=2, nudge_s=0))
    sender.start()
    commands = program(2)
    done = sender.stream(commands)
    with pytest.raises(PrinterSilent, match=rf"while line 0 \({commands[0]}\) was unacknowledged, after 2 probes"):
        await asyncio.wait_for(done, 3)
    assert [c for _, c in wire.lines].count("M105") == 2
    assert sender.probes == 2


async def test_after_a_probe_numbering_and_resends_go_on_from_it() -> None:
    """The probe takes the next number; once its ok T: proves line 0, the program goes on with the
    number after the probe, and a later request counts exactly the lines sent after it."""
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.1, probes=3, nudge_s=0,
                                                          resend_settle_s=10))
    sender.start()
    commands = program(3)
    done = sender.stream(commands)
    await wait_for_line(wire, "M105")
    feed(sender, "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")  # the probe's answer: line 0 ran
    assert wire.lines == [(0, commands[0]), (1, "M105"), (2, commands[1])]
    # Line 2 refused: nothing was sent after it, so it goes again at once (no stale request due).
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    assert wire.lines[-1] == (2, commands[1])
    feed(sender, "ok", "ok")
    result = await asyncio.wait_for(done, 1)
    assert (result.probes, result.resends) == (1, 1)
    assert wire.lines[-1] == (3, commands[2])
    sender.stop(StreamCancelled("test over"))


async def test_a_probe_behind_rewound_lines_follows_them_whatever_the_window() -> None:
    """Ping-pong: the probe (line 1) drew a request for line 0, which goes again alone; when line 0
    meets silence again, the rewound probe line goes out with the new probe right behind it
    (ADVANCED_OK firmware: a re-sent line is not held alone for its own ok)."""
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.15, probes=3, nudge_s=0,
                                                          resend_settle_s=0.01))
    sender.capabilities.advanced_ok = True
    sender.start()
    commands = program(2)
    done = sender.stream(commands)
    await wait_for_line(wire, "M105")
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: -1", "Resend: 0", "ok")
    await wait_for_line(wire, "M105", count=2)
    assert wire.lines == [(0, commands[0]), (1, "M105"), (0, commands[0]), (1, "M105"), (2, "M105")]
    feed(sender, "ok N0 P15 B3", "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0", "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")
    assert wire.lines[-1] == (3, commands[1])
    feed(sender, "ok N3 P15 B3")
    assert (await asyncio.wait_for(done, 1)).probes == 2
    sender.stop(StreamCancelled("test over"))


async def test_answers_carry_the_ok_that_acknowledged_them() -> None:
    sender, wire = make()
    move = sender.send("G1 X1")
    feed(sender, "ok")
    assert isinstance((await asyncio.wait_for(move, 1)).ok, codec.Ok)
    query = sender.send("M105")
    feed(sender, "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")
    assert (await asyncio.wait_for(query, 1)).ok.temperatures is not None
    advanced = sender.send("G1 X2")
    feed(sender, "ok P15 B3")                        # ADVANCED_OK without N: the oldest's
    assert (await asyncio.wait_for(advanced, 1)).ok.queue_free == 3
    numbered = sender.send("G1 X3")
    feed(sender, "ok N3 P15 B2")
    assert (await asyncio.wait_for(numbered, 1)).ok.queue_free == 2


async def test_a_temperature_ok_with_no_query_outstanding_answers_the_oldest_line() -> None:
    sender, wire = make()
    move = sender.send("G1 X1")
    feed(sender, "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")
    assert (await asyncio.wait_for(move, 1)).ok.temperatures is not None


async def test_the_window_refills_to_the_byte_as_lines_are_acknowledged() -> None:
    sender, wire = make(rx=127)
    commands = program(30)
    done = sender.stream(commands)
    for acknowledged in range(3):
        feed(sender, "ok")
        unacknowledged = [n for n in wire.numbers() if n > acknowledged]
        in_flight = sizes(wire, unacknowledged)
        following = len(codec.encode(len(wire.lines), commands[len(wire.lines)]))
        assert in_flight <= 127 < in_flight + following
    done.cancel()


async def test_a_nudge_takes_exactly_one_byte_until_its_line_is_acknowledged() -> None:
    size = len(codec.encode(0, EQUAL[0]))
    assert all(len(codec.encode(n, c)) == size for n, c in enumerate(EQUAL))
    # room for two lines and the nudge's newline: line 2 fits once line 0 is acknowledged
    sender, wire = make(rx=2 * size + 1, timeouts=Timeouts(nudge_s=0.05, default_s=5))
    sender.start()
    done = sender.stream(EQUAL[:3])
    await asyncio.sleep(0.15)
    assert wire.nudges == 1 and sender.nudges == 1
    feed(sender, "ok")
    assert wire.numbers() == [0, 1, 2]
    feed(sender, "ok", "ok")
    assert (await asyncio.wait_for(done, 1)).nudges == 1
    sender.stop(StreamCancelled("test over"))


async def test_a_nudges_byte_is_freed_with_the_line_it_followed() -> None:
    size = len(codec.encode(0, EQUAL[0]))
    sender, wire = make(rx=2 * size, timeouts=Timeouts(nudge_s=0.05, default_s=5))
    sender.start()
    done = sender.stream(EQUAL[:4])
    assert wire.numbers() == [0, 1]
    await asyncio.sleep(0.15)                        # nudged behind line 1
    feed(sender, "ok")
    assert wire.numbers() == [0, 1]
    feed(sender, "ok")                               # line 1, and the newline read after it
    assert wire.numbers() == [0, 1, 2, 3], "two lines' room again, the nudge's byte free"
    feed(sender, "ok", "ok")
    await asyncio.wait_for(done, 1)
    assert sender.nudges == 1
    sender.stop(StreamCancelled("test over"))


async def test_the_window_governor_is_told_the_refused_lines_bytes_in_flight_once_an_episode() -> None:
    """The governor judges overflow by how many bytes were in flight when the refused line was
    sent; the stale lines' errors after it are the same episode and are not told."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    told: list[int | None] = []
    sender.window.line_error = told.append
    done = sender.stream(program(10))
    sent = wire.numbers()
    offset = sizes(wire, [0, 1, 2])                 # line 2 went out with lines 0 and 1 unacknowledged
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    for _ in sent[3:]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 1", "Resend: 2", "ok")
    assert told == [offset]
    feed(sender, "Error:checksum mismatch")           # no line named: the offset is not known
    assert told[-1] is None
    done.cancel()


async def test_an_ok_naming_a_line_past_the_last_one_sent_counts_the_lines_sent() -> None:
    sender, wire = make(rx=4096)
    done = sender.stream(program(6))
    assert wire.numbers() == [0, 1, 2, 3]
    feed(sender, "ok N9 P15 B3")
    assert sender.last_acknowledged_line == 3
    feed(sender, "ok N4 P15 B3", "ok N5 P15 B3")
    assert (await asyncio.wait_for(done, 1)).lines == 6


async def test_an_ok_on_receipt_acknowledging_several_lines_answers_each() -> None:
    """Repetier numbers its oks; one ``ok 2`` (the others lost) covers lines 0 to 2: the M105 is
    answered at once, the G1 (acknowledged on receipt) only once the M114 behind it reports."""
    wire = Wire()
    caps = Capabilities(rx_buffer_bytes=4096)
    caps.use_dialect("repetier")
    sender = Sender(wire.write, caps)
    move = sender.send("G1 X1")
    query = sender.send("M105")
    assert wire.lines == [(0, "G1 X1"), (1, "M114"), (2, "M105")]
    feed(sender, "ok 2")
    assert (await asyncio.wait_for(query, 1)).line == 2
    assert not move.done()
    feed(sender, "X:1.00 Y:0.00 Z:0.00 E:0.0000")
    assert (await asyncio.wait_for(move, 1)).ok.line == 2


async def test_a_stopped_sender_fails_every_waiting_answer_and_refuses_more() -> None:
    sender, wire = make()
    first, second = sender.send("G1 X1"), sender.send("G1 X2")
    reason = ProtocolError("the link closed")
    sender.stop(reason)
    for future in (first, second):
        with pytest.raises(ProtocolError) as raised:
            await asyncio.wait_for(future, 1)
        assert raised.value is reason
    with pytest.raises(ProtocolError, match="the link closed"):
        sender.send("M105")
    sender.stop(LinkError("a second reason"))
    with pytest.raises(ProtocolError, match="the link closed"):
        sender.send("M105")


async def test_answers_after_stop_during_a_hold_are_taken_quietly() -> None:
    """The link may still read the printer's lines after the sender stopped in a resend hold."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(10))
    sent = len(wire.lines)
    feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 0", "ok")
    sender.stop(ProtocolError("the operator stopped"))
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: -1", "Resend: 0", "ok", "skip 3")
    sender.cancel()
    assert len(wire.lines) == sent
    with pytest.raises(ProtocolError, match="the operator stopped"):
        await asyncio.wait_for(done, 1)


async def test_no_second_program_while_one_streams() -> None:
    sender, wire = make()
    sender.stream(program(3))
    with pytest.raises(LinkError, match=r"^a program is already streaming$"):
        sender.stream(program(1))
    with pytest.raises(LinkError, match=r"^cannot reset line numbers while commands are outstanding$"):
        sender.reset_line_numbers()


async def test_no_reset_while_a_paused_program_has_lines_to_send() -> None:
    sender, wire = make(rx=127)
    sender.stream(program(20))
    sender.pause()
    feed(sender, *["ok"] * len(wire.lines))
    assert sender.in_flight == 0
    with pytest.raises(LinkError, match="outstanding"):
        sender.reset_line_numbers()


def repetier(**kwargs) -> tuple[Sender, Wire]:
    wire = Wire()
    caps = Capabilities(rx_buffer_bytes=4096)
    caps.use_dialect("repetier")
    return Sender(wire.write, caps, **kwargs), wire


async def test_a_reset_fails_answers_still_waiting_for_their_proof() -> None:
    sender, wire = repetier()
    move = sender.send("G1 X1")
    feed(sender, "ok 0", "ok 1")                      # received, and its M114 received: not yet run
    sender.reset_line_numbers()
    with pytest.raises(LinkError, match=r"^line numbers reset before the command was proven run$"):
        await asyncio.wait_for(move, 1)


async def test_after_a_reset_a_program_streams_and_resends_count_from_the_new_numbers() -> None:
    """A handshake after an earlier session: M110 N0 is line 0, the program numbers from 1, and a
    resend episode expects exactly one request per line sent after the line asked for."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    sender.send("M105")
    feed(sender, "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0")
    reset = sender.reset_line_numbers()
    feed(sender, "ok")
    await asyncio.wait_for(reset, 1)
    start = len(wire.lines)
    done = sender.stream(program(8))
    window = [n for n, _ in wire.lines[start:]]
    assert window[0] == 1 and len(window) >= 4
    feed(sender, "ok")                                # line 1
    window = [n for n, _ in wire.lines[start:]]
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    for _ in window[2:]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 1", "Resend: 2", "ok")
    assert wire.lines[start + len(window)][0] == 2, "resent at once: every stale line answered"
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0)
    assert done.result().lines == 8


async def test_after_a_reset_skips_and_cut_tails_are_counted_afresh() -> None:
    sender, wire = repetier(timeouts=Timeouts(resend_settle_s=10))
    reset = sender.reset_line_numbers()
    feed(sender, "ok 0")
    await asyncio.wait_for(reset, 1)
    done = sender.stream(program(4))
    feed(sender, "Error:Wrong checksum", "Resend:1", "ok", "skip 2", "ok", "skip 3", "ok", "skip 4")
    assert wire.numbers()[-4:] == [1, 2, 3, 4]
    feed(sender, "ok")
    assert sender.last_acknowledged_line == 0, "the skips' oks acknowledged nothing"
    feed(sender, "ok 1", "ok 2", "ok 3", "ok 4")
    assert (await asyncio.wait_for(done, 1)).lines == 4


async def test_a_reset_on_dropping_firmware_names_the_lines_since_the_reset() -> None:
    """RepRapFirmware: a query answered before the reset does not bound the lines after it."""
    wire = Wire()
    caps = Capabilities(rx_buffer_bytes=4096)
    caps.use_dialect("reprapfirmware")
    sender = Sender(wire.write, caps)
    for _ in range(3):
        sender.send("M105")
        feed(sender, "ok T:25.0 /0.0 B:25.0 /0.0")
    reset = sender.reset_line_numbers()
    feed(sender, "ok")
    await asyncio.wait_for(reset, 1)
    done = sender.stream(["G1 X1", "G1 X2", "M400"])
    assert wire.lines[-4:] == [(1, "G1 X1"), (2, "G1 X2"), (3, "M400"), (4, "M105")]
    feed(sender, "ok", "ok", "ok T:25.0 /0.0 B:25.0 /0.0")     # one of 0 to 3 was dropped
    with pytest.raises(ProtocolError, match=r"one of lines 0 to 3 may never have run"):
        await asyncio.wait_for(done, 1)
