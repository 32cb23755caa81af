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

    def write(self, data: bytes) -> None:
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


async def test_resend_waits_for_stale_requests_then_resends_once() -> None:
    sender, wire = make(rx=127, timeouts=SETTLE)
    done = sender.stream(program(10))
    feed(sender, "ok")  # line 0 processed; the window moves on
    first_window = wire.numbers()
    assert first_window[0] == 0 and len(first_window) >= 4
    # Line 1 arrived corrupted: Marlin flushes its buffer and asks for 1 (then a plain ok). The
    # other lines of the window still reach its parser and are refused the same way.
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    for _ in first_window[2:]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok")
    assert wire.numbers() == first_window, "nothing goes out while stale requests may still come"
    await asyncio.sleep(0.05)
    assert wire.numbers()[len(first_window)] == 1, "then the resend starts at the line asked for"
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0)
    result = done.result()
    assert result.lines == 10 and result.resends == 1
    sent = wire.numbers()
    assert sorted(set(sent)) == list(range(10))
    assert all(sent.count(n) == 2 for n in first_window[1:]), "the refused lines went out again, once"
    assert all(sent.count(n) == 1 for n in range(10) if n == 0 or n not in first_window)


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
