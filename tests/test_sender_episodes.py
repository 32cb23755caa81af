"""The sender through whole protocol episodes on scripted answers (issue 35, the mutation run's
survivors): a re-sent line proven by its position (and the lines after it renumbered), queries'
answers that acknowledge through them, cut tails and Repetier's skips on plain-ok firmware, a
request for the line not yet sent, barriers, small histories, and the watchdog's clock. Each
scenario is what the firmware prints (Marlin's ``Resend:``/``ok``, Repetier's ``skip``,
Smoothieware's ``ok C:``, RepRapFirmware's silent drop)."""

from __future__ import annotations

import asyncio
import time

import pytest

from ribbond.printer import codec
from ribbond.printer.capabilities import Capabilities
from ribbond.printer.errors import PrinterSilent, ProtocolError, StreamCancelled
from ribbond.printer.sender import Sender, Timeouts

from .test_sender import Wire, ack_numbered_from, feed, make, moves, plain_resend, program, resend_episode

TEMPERATURES = "ok T:20.0 /0.0 B:20.0 /0.0 @:0 B@:0"


def dialect(name: str, **kwargs) -> tuple[Sender, Wire]:
    wire = Wire()
    caps = Capabilities(rx_buffer_bytes=4096)
    caps.use_dialect(name)
    return Sender(wire.write, caps, **kwargs), wire


async def until(wire: Wire, command: str, count: int = 1, limit: float = 3.0) -> None:
    deadline = asyncio.get_running_loop().time() + limit
    while sum(c == command for _, c in wire.lines) < count:
        assert asyncio.get_running_loop().time() < deadline, f"no {command} sent"
        await asyncio.sleep(0.01)


async def finish(sender: Sender, done: asyncio.Future, answer: str = "ok") -> None:
    for _ in range(200):
        if done.done():
            break
        feed(sender, answer)
        await asyncio.sleep(0.005)
    await asyncio.wait_for(done, 1)


# ---- a re-sent line on plain-ok firmware, proven by M400 + M114

async def proof_out(sender: Sender, wire: Wire, commands: list[str], acked: int, asked: int) -> asyncio.Future:
    """Stream ``commands``; lines before ``acked`` acknowledged, line ``asked`` refused and sent
    again, then no ok: returns once the proof's M114 is out."""
    sender.start()
    done = sender.stream(commands)
    feed(sender, *["ok"] * acked)
    plain_resend(sender, wire, asked)
    await until(wire, "M114")
    return done


def silent_resend(**timeouts) -> tuple[Sender, Wire]:
    return make(rx=127, timeouts=Timeouts(resend_settle_s=10, default_s=0.1, nudge_s=0, **timeouts))


#: Absolute moves 1 mm apart: line k >= 1 leaves the printer at X(8 + k), Y5.
STEPS = ["G90", "G1 X9 Y5", "G1 X10 Y5", "G1 X11 Y5", "G1 X12 Y5"]


def at(x: int) -> str:
    return f"X:{x}.00 Y:5.00 Z:0.00 E:0.00 Count X:0 Y:0 Z:0"


@pytest.mark.parametrize("asked", [2, 3])
async def test_the_lines_after_a_proven_line_go_again_once_numbered_after_the_proof(asked: int) -> None:
    """Two lines (or one) were numbered after the silent re-sent line: they give their numbers back
    and go out after M400 + M114, each once, in program order."""
    sender, wire = silent_resend()
    done = await proof_out(sender, wire, STEPS, acked=asked, asked=asked)
    assert wire.lines[-2:] == [(asked + 1, "M400"), (asked + 2, "M114")]
    feed(sender, "ok", at(8 + asked), "ok")
    await finish(sender, done)
    after = wire.lines[wire.lines.index((asked + 2, "M114")) + 1:]
    assert after == [(asked + 3 + i, c) for i, c in enumerate(STEPS[asked + 1:])]
    sender.stop(StreamCancelled("test over"))


async def test_a_command_sent_after_the_silent_line_is_answered_after_the_proof() -> None:
    sender, wire = silent_resend()
    sender.start()
    done = sender.stream(STEPS)
    assert wire.numbers() == [0, 1, 2, 3]
    temperature = sender.send("M104 S200")             # waits for a slot of the queue
    feed(sender, "ok")                                 # line 0: the M104 goes out as line 4
    assert wire.lines[-1] == (4, "M104 S200")
    feed(sender, "ok")                                 # line 1: program line 5 goes out as line 5
    plain_resend(sender, wire, 2)
    await until(wire, "M114")
    assert wire.lines[-2:] == [(3, "M400"), (4, "M114")]
    feed(sender, "ok", at(10), "ok")
    after = wire.lines[wire.lines.index((4, "M114")) + 1:]
    assert after[0] == (5, "M104 S200"), "the command first, renumbered after the proof"
    feed(sender, "ok")
    assert (await asyncio.wait_for(temperature, 1)).command == "M104 S200"
    await finish(sender, done)
    assert wire.lines[-2:] == [(6, STEPS[3]), (7, STEPS[4])]
    sender.stop(StreamCancelled("test over"))


async def test_a_proof_that_finds_the_line_not_run_names_both_positions() -> None:
    sender, wire = silent_resend()
    commands = moves(4)                                # G90, then X10, X11, X12, X13 at Y5
    done = await proof_out(sender, wire, commands, acked=2, asked=2)
    feed(sender, "ok", "X:10.00 Y:5.00 Z:0.30 E:0.00 Count X:0 Y:0 Z:0", "ok")
    with pytest.raises(ProtocolError, match=r"after M400 it is at X10, Y5, Z0\.3, not at X11, Y5 where"):
        await asyncio.wait_for(done, 1)


async def test_smoothiewares_ok_with_the_position_concludes_the_proof() -> None:
    """Smoothieware prints M114's position in its ``ok C: X:… Y:… Z:…``."""
    sender, wire = silent_resend()
    sender.capabilities.position_report = "ok"
    commands = moves(4)
    done = await proof_out(sender, wire, commands, acked=2, asked=2)
    feed(sender, "ok", "ok C: X:11.0000 Y:5.0000 Z:0.0000 E:0.0000")
    assert sender.last_acknowledged_line == 4
    await finish(sender, done)
    sender.stop(StreamCancelled("test over"))


async def test_a_proof_that_draws_no_answer_stops_the_stream_naming_the_line() -> None:
    sender, wire = silent_resend()
    commands = moves(4)
    done = await proof_out(sender, wire, commands, acked=2, asked=2)
    with pytest.raises(ProtocolError, match=rf"no answer for \d+\.\d s to M400 \+ M114 sent to prove that line 2 "
                                            rf"\(program line 3: {commands[2]}\) ran"):
        await asyncio.wait_for(done, 2)


async def test_a_request_during_the_proof_stops_the_stream_naming_the_line() -> None:
    sender, wire = silent_resend()
    commands = moves(4)
    done = await proof_out(sender, wire, commands, acked=2, asked=2)
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3")
    with pytest.raises(ProtocolError, match=rf"asked for line 3 while M400 \+ M114 were proving that line 2 "
                                            rf"\(program line 3: {commands[2]}\) ran: stopped with line 1"):
        await asyncio.wait_for(done, 1)


async def test_after_a_proof_a_request_counts_only_the_lines_sent_after_it() -> None:
    sender, wire = silent_resend()
    commands = moves(8)
    done = await proof_out(sender, wire, commands, acked=2, asked=2)
    feed(sender, "ok", "X:11.00 Y:5.00 Z:0.00 E:0.00 Count X:0 Y:0 Z:0", "ok")
    last = wire.numbers()[-1]
    feed(sender, f"Error:checksum mismatch, Last Line: {last - 1}", f"Resend: {last}", "ok")
    assert wire.numbers()[-1] == last and wire.numbers().count(last) == 2, "nothing stale: resent at once"
    await finish(sender, done)
    sender.stop(StreamCancelled("test over"))


async def test_a_silent_resent_command_outside_a_program_stops_the_stream() -> None:
    """Only a program's move has a position that proves it ran."""
    sender, wire = silent_resend()
    sender.start()
    first, second = sender.send("G1 X10 Y5"), sender.send("G1 X11 Y5")
    feed(sender, "ok")
    plain_resend(sender, wire, 1)
    with pytest.raises(ProtocolError, match=r"no ok for line 1, which it had asked for again.*not a move"):
        await asyncio.wait_for(second, 2)
    assert first.done() and "M114" not in [c for _, c in wire.lines]


async def test_a_request_past_the_resent_line_clears_it_and_the_stream_goes_on() -> None:
    """Its line-number check refused the copy: the printer had the line from the first pass."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=0.01))
    done = sender.stream(moves(6))
    feed(sender, "ok", "ok")
    plain_resend(sender, wire, 2)
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3", "ok")
    await asyncio.sleep(0.05)
    assert wire.lines[-1][0] == 3, "resent from 3"
    await finish(sender, done)


async def test_a_resent_line_acknowledged_after_a_request_past_it_counts_fast() -> None:
    """As test_sender's Marlin-order case, with a short settle time (no 10 s wait)."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=0.01))
    done = sender.stream(program(10))
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3")
    resend_episode(sender, wire, 2)
    feed(sender, "Error:checksum mismatch, Last Line: 2", "Resend: 3", "ok")
    feed(sender, "ok N2 P15 B3")
    await asyncio.sleep(0.05)
    assert sender.last_acknowledged_line == 2
    await ack_numbered_from(sender, done, 3)
    assert done.result().lines == 10


async def test_a_line_asked_for_twice_then_acknowledged_past_by_number_counts() -> None:
    """With ADVANCED_OK a numbered ok proves every line before it ran: a line the printer asked for
    again twice (its copy destroyed by a flush) needs no ok of its own then."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=0.01))
    done = sender.stream(program(6))
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3")
    resend_episode(sender, wire, 2)
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    await asyncio.sleep(0.05)
    feed(sender, "ok N3 P15 B3")
    assert sender.last_acknowledged_line == 3
    await ack_numbered_from(sender, done, 4)
    assert done.result().lines == 6


async def test_a_refused_command_outside_a_program_is_named_by_its_number() -> None:
    sender, wire = make()
    first, second = sender.send("G1 X1"), sender.send("G1 X2")
    feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 1")
    with pytest.raises(ProtocolError, match=r"after refusing line 0, which was not sent again"):
        await asyncio.wait_for(first, 1)


async def test_a_request_for_a_line_never_sent_names_the_last_one_sent() -> None:
    sender, wire = make()
    done = sender.stream(program(10))
    last = wire.numbers()[-1]
    feed(sender, "Resend: 50")
    with pytest.raises(ProtocolError, match=rf"^printer asked to resend line 50, which was never sent "
                                            rf"\(last line sent: {last}\)$"):
        await asyncio.wait_for(done, 1)


async def test_a_request_for_the_next_line_after_everything_was_acknowledged_is_harmless() -> None:
    """Noise on an empty line makes Marlin ask for the line after the last it took: nothing to send
    again, and the next lines go out as usual (several in flight, not one alone)."""
    sender, wire = make(rx=127)
    done = sender.stream(program(1))
    feed(sender, "ok")
    await asyncio.wait_for(done, 1)
    feed(sender, "Error:No Line Number with checksum, Last Line: 0", "Resend: 1", "ok")
    await asyncio.sleep(0)
    again = sender.stream(program(6))
    assert wire.numbers()[1:] == [1, 2, 3, 4]
    await finish(sender, again)


async def test_a_request_for_the_last_line_sent_resends_it_in_the_room_it_left() -> None:
    """ADVANCED_OK, a window of two lines, a nudge behind line 1: the printer asks for line 1 (the
    newline was flushed with it): line 1 goes again at once, in exactly its own room."""
    size = len(codec.encode(0, "G1 X10 Y10 F3000"))
    lines = [f"G1 X{10 * (i + 1)} Y10 F3000" for i in range(3)]
    sender, wire = make(rx=2 * size, timeouts=Timeouts(nudge_s=0.05, default_s=5, resend_settle_s=10))
    sender.capabilities.advanced_ok = True
    sender.start()
    done = sender.stream(lines)
    await asyncio.sleep(0.15)
    assert wire.nudges == 1 and wire.numbers() == [0, 1]
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    assert wire.numbers() == [0, 1, 1]
    feed(sender, "ok N0 P15 B3", "ok N1 P15 B3", "ok N2 P15 B3")
    assert (await asyncio.wait_for(done, 1)).lines == 3
    sender.stop(StreamCancelled("test over"))


# ---- queries' answers

async def test_a_plain_ok_answers_only_the_oldest_line_with_a_query_in_flight() -> None:
    sender, wire = make()
    move, query = sender.send("G1 X1"), sender.send("M114")
    feed(sender, "ok")
    await asyncio.wait_for(move, 1)
    assert not query.done() and sender.last_acknowledged_line == 0


async def test_a_temperature_answer_acknowledges_its_own_query_only() -> None:
    sender, wire = make()
    first = sender.send("M105")
    feed(sender, TEMPERATURES)
    assert (await asyncio.wait_for(first, 1)).line == 0
    second, third = sender.send("M105"), sender.send("M105")
    feed(sender, TEMPERATURES)
    assert (await asyncio.wait_for(second, 1)).line == 1
    assert not third.done()
    feed(sender, TEMPERATURES)
    assert (await asyncio.wait_for(third, 1)).line == 2


async def test_smoothiewares_position_ok_acknowledges_its_m114_and_the_lines_before() -> None:
    sender, wire = dialect("smoothieware")
    move, query = sender.send("G1 X1"), sender.send("M114")
    feed(sender, "ok C: X:1.0000 Y:0.0000 Z:0.0000 E:0.0000")  # the G1's ok was lost
    assert (await asyncio.wait_for(query, 1)).ok.position is not None
    assert move.done() and sender.last_acknowledged_line == 1


async def test_reprapfirmware_names_the_lines_since_the_last_query_answered() -> None:
    sender, wire = dialect("reprapfirmware")
    done = sender.stream(["G1 X1", "M400", "G1 X2", "G1 X3", "M400", "G1 X4"])
    assert wire.lines[:3] == [(0, "G1 X1"), (1, "M400"), (2, "M105")]
    feed(sender, "ok", "ok", TEMPERATURES)            # the first part: all there
    assert wire.lines[3:7] == [(3, "G1 X2"), (4, "G1 X3"), (5, "M400"), (6, "M105")]
    feed(sender, "ok", "ok", TEMPERATURES)            # one of 3 to 5 dropped
    with pytest.raises(ProtocolError, match=r"answered line 6 \(M105\) while line 5 \(program line 5: M400\) "
                                            r"was unacknowledged.*one of lines 3 to 5 may never have run"):
        await asyncio.wait_for(done, 1)


# ---- cut tails and skips where oks carry no number

async def test_cut_tails_oks_acknowledge_nothing_on_plain_ok_firmware() -> None:
    """Marlin without ADVANCED_OK runs the tail of a line cut by its flush as an unknown command
    and answers it with a plain ``ok``: one per tail, none of them the re-sent line's."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(moves(6))
    feed(sender, "ok")
    plain_resend(sender, wire, 1)
    assert wire.numbers()[-1] == 1
    for tail in ('"Y5*85"', '"5*12"'):
        feed(sender, f"echo:Unknown command: {tail}")
    feed(sender, "ok", "ok")
    assert sender.last_acknowledged_line == 0, "the tails' oks acknowledged the re-sent line"
    feed(sender, "ok")
    assert sender.last_acknowledged_line == 1
    await finish(sender, done)


async def test_an_unknown_command_without_a_checksum_is_answered_by_an_ok_that_counts() -> None:
    sender, wire = make()
    move = sender.send("G1 X1")
    feed(sender, 'echo:Unknown command: "G1 X1"', "ok")
    assert (await asyncio.wait_for(move, 1)).line == 0


async def test_a_plain_ok_during_the_hold_acknowledges_nothing_from_the_line_asked_for() -> None:
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(8))
    feed(sender, "ok")
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok", "ok")
    assert sender.last_acknowledged_line == 0
    done.cancel()


async def test_repetiers_skips_oks_without_numbers_acknowledge_nothing() -> None:
    """Repetier with its oks unnumbered: ``skip N`` + ``ok`` per stale line, then the resent lines'
    plain oks acknowledge in order."""
    sender, wire = dialect("repetier", timeouts=Timeouts(resend_settle_s=5.0))
    done = sender.stream(program(5))
    feed(sender, "ok")
    assert wire.numbers() == [0, 1, 2, 3, 4]
    feed(sender, "Error:Wrong checksum", "Resend:1", "ok", "skip 2", "ok", "skip 3", "ok", "skip 4", "ok")
    assert wire.numbers()[5:] == [1, 2, 3, 4]
    assert sender.last_acknowledged_line == 0
    for number in range(1, 5):
        feed(sender, "ok")
        assert sender.last_acknowledged_line == number
    assert (await asyncio.wait_for(done, 1)).lines == 5


async def test_a_cancelled_program_does_not_hold_the_next_behind_its_m400() -> None:
    sender, wire = dialect("repetier")
    first = sender.stream(["G1 X1", "M400", "G1 X2"])
    feed(sender, "ok 0", "ok 1")                       # the M400 received, its proof not yet in
    sender.cancel()
    feed(sender, "ok 2")
    with pytest.raises(StreamCancelled):
        await asyncio.wait_for(first, 1)
    second = sender.stream(["G1 X3"])
    assert wire.lines[-1] == (3, "G1 X3")
    feed(sender, "ok 3")
    assert (await asyncio.wait_for(second, 1)).lines == 1


# ---- barriers, histories

async def test_a_barrier_line_waits_until_every_line_before_it_is_acknowledged() -> None:
    sender, wire = make(rx=4096)
    done = sender.stream(program(4), barriers=frozenset({2}))
    assert wire.numbers() == [0, 1]
    feed(sender, "ok")
    assert wire.numbers() == [0, 1]
    feed(sender, "ok")
    assert wire.numbers() == [0, 1, 2, 3]
    await finish(sender, done)


async def test_a_history_of_no_acknowledged_lines_still_keeps_every_line_in_flight() -> None:
    sender, wire = make(rx=127, history=0, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(12))
    feed(sender, "ok", "ok", "ok")
    window = wire.numbers()
    feed(sender, "Error:checksum mismatch, Last Line: 2", "Resend: 3", "ok")
    for _ in [n for n in window if n > 3]:
        feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3", "ok")
    assert wire.numbers()[len(window)] == 3, "the line asked for was still there to send"
    await finish(sender, done)


# ---- the watchdog's clock

@pytest.mark.parametrize("nudge_s", [0, 3.0])
async def test_the_watchdog_looks_at_least_every_50_ms(nudge_s: float) -> None:
    sender, wire = make(timeouts=Timeouts(default_s=0.1, probes=1, nudge_s=nudge_s))
    sender.start()
    done = sender.stream(program(1))
    with pytest.raises(PrinterSilent):
        await asyncio.wait_for(done, 1.5)              # two 0.1 s silences, seen within 50 ms each


async def test_the_silence_clock_starts_with_the_first_line_out_after_an_idle_time() -> None:
    sender, wire = make(timeouts=Timeouts(default_s=0.3, probes=2, nudge_s=0))
    sender.start()
    await asyncio.sleep(0.5)                           # idle: nothing in flight, nothing heard
    done = sender.stream(program(1))
    await asyncio.sleep(0.1)
    assert "M105" not in [c for _, c in wire.lines], "probed for a silence that began before the line"
    await until(wire, "M105")                          # the watchdog still watches
    feed(sender, TEMPERATURES)
    await asyncio.wait_for(done, 1)
    sender.stop(StreamCancelled("test over"))


async def test_the_watchdog_goes_on_after_a_wait_for_the_user_and_after_a_hold() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.15, probes=3, nudge_s=0,
                                                          resend_settle_s=0.2))
    sender.capabilities.advanced_ok = True             # (a re-sent line is not held alone for its ok)
    sender.start()
    pause = sender.send("M0")
    await asyncio.sleep(0.2)                           # M0 waits for the user: no probe
    assert wire.lines == [(0, "M0")]
    feed(sender, "ok N0 P15 B3")
    await asyncio.wait_for(pause, 1)
    move = sender.send("G1 X1")
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    await asyncio.sleep(0.1)                           # holding (0.2 s settle): no probe meanwhile
    await until(wire, "G1 X1", count=2)
    await until(wire, "M105")                          # then silence again: probed
    feed(sender, TEMPERATURES)
    assert (await asyncio.wait_for(move, 1)).line == 1
    sender.stop(StreamCancelled("test over"))


async def test_busy_keeps_a_move_alive_and_silence_after_it_is_probed() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.15, probes=2, nudge_s=0))
    sender.start()
    move = sender.send("G1 X100")
    for _ in range(6):
        await asyncio.sleep(0.05)
        feed(sender, "echo:busy: processing")
    assert wire.numbers() == [0], "no probe while the printer says it is busy"
    await until(wire, "M105")
    feed(sender, TEMPERATURES)
    assert (await asyncio.wait_for(move, 1)).line == 0
    sender.stop(StreamCancelled("test over"))



# ---- more edges the mutation run found

async def test_each_silence_is_nudged_and_counted() -> None:
    sender, wire = make(timeouts=Timeouts(nudge_s=0.1, default_s=5))
    sender.start()
    done = sender.stream(program(1))
    await asyncio.sleep(0.35)
    feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 0", "ok")
    await asyncio.sleep(0.3)
    assert wire.nudges == 2 and sender.nudges == 2
    feed(sender, "ok N0 P15 B3")
    assert (await asyncio.wait_for(done, 1)).nudges == 2
    sender.stop(StreamCancelled("test over"))


async def test_a_request_past_the_last_resent_line_leaves_nothing_alone_and_the_probe_settles_it() -> None:
    """The re-sent line was the last one numbered and its copy is refused (the printer had it):
    nothing is left to send alone; the silence probe's answer acknowledges it."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=0.01, default_s=0.1, nudge_s=0))
    sender.start()
    done = sender.stream(moves(2))                    # lines 0 to 2
    feed(sender, "ok", "ok")
    plain_resend(sender, wire, 2)
    assert wire.numbers()[-2:] == [2, 2]
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3", "ok")
    await until(wire, "M105")
    feed(sender, TEMPERATURES)
    assert (await asyncio.wait_for(done, 1)).lines == 3
    sender.stop(StreamCancelled("test over"))


async def test_the_watchdog_still_probes_after_probing_behind_rewound_lines() -> None:
    sender, wire = make(ping_pong=True, timeouts=Timeouts(default_s=0.15, probes=3, nudge_s=0,
                                                          resend_settle_s=0.01))
    sender.capabilities.advanced_ok = True
    sender.start()
    sender.send("G1 X1")
    await until(wire, "M105")
    feed(sender, "Error:Line Number is not Last Line Number+1, Last Line: -1", "Resend: 0", "ok")
    await until(wire, "M105", count=2)                 # line 1 (the old probe) and the probe 2
    await until(wire, "M105", count=4)                 # silence again: they go again, with a probe
    sender.stop(StreamCancelled("test over"))


async def test_the_watchdog_goes_on_through_a_hold_with_lines_in_flight() -> None:
    sender, wire = make(rx=127, timeouts=Timeouts(default_s=0.15, probes=3, nudge_s=0, resend_settle_s=0.3))
    sender.capabilities.advanced_ok = True
    sender.start()
    sender.stream(program(4))
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")  # line 0 still in flight
    await asyncio.sleep(0.2)                           # holding: no probe
    assert "M105" not in [c for _, c in wire.lines]
    await until(wire, "M105")
    sender.stop(StreamCancelled("test over"))


async def test_a_silent_resent_command_during_a_program_stops_the_stream() -> None:
    sender, wire = silent_resend()
    sender.start()
    done = sender.stream(STEPS)
    temperature = sender.send("M104 S200")
    feed(sender, "ok", "ok", "ok", "ok")               # lines 0 to 3; the M104 is line 4
    assert (4, "M104 S200") in wire.lines
    plain_resend(sender, wire, 4)
    with pytest.raises(ProtocolError, match=r"no ok for line 4, which it had asked for again.*not a move"):
        await asyncio.wait_for(temperature, 2)
    with pytest.raises(ProtocolError):
        await asyncio.wait_for(done, 1)


async def test_answers_after_stop_in_a_hold_do_not_end_the_hold_again() -> None:
    """Stopped while holding; the stale lines' requests and skips still arrive: taken quietly."""
    sender, wire = make(rx=127, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(10))
    sent = wire.numbers()
    feed(sender, "Error:checksum mismatch, Last Line: -1", "Resend: 0", "ok")
    sender.stop(ProtocolError("the operator stopped"))
    feed(sender, *[f"skip {n}" for n in sent])
    feed(sender, *["Resend: 0"] * len(sent))
    assert wire.numbers() == sent
    with pytest.raises(ProtocolError, match="the operator stopped"):
        await asyncio.wait_for(done, 1)


async def test_a_programs_m400_and_a_command_proven_by_one_wait_both_count() -> None:
    """Repetier: the program's M400 and a command sent meanwhile, both received and not yet proven
    run; its ``wait`` (buffer empty) proves both: the M400 counts and the program finishes."""
    sender, wire = dialect("repetier")
    done = sender.stream(["G1 X1", "M400", "G1 X2"])
    temperature = sender.send("M104 S200")
    feed(sender, "ok 0")                               # (four lines in flight at most)
    assert wire.lines == [(0, "G1 X1"), (1, "M400"), (2, "M114"), (3, "M104 S200"), (4, "M114")]
    feed(sender, "ok 1", "ok 2", "ok 3", "ok 4", "wait")
    assert (await asyncio.wait_for(temperature, 1)).command == "M104 S200"
    assert wire.lines[-1] == (5, "G1 X2")
    feed(sender, "ok 5")
    assert (await asyncio.wait_for(done, 1)).lines == 3


async def test_a_line_error_during_the_proof_still_tells_the_window_governor() -> None:
    sender, wire = silent_resend()
    told: list[int | None] = []
    sender.window.line_error = told.append
    done = await proof_out(sender, wire, moves(4), acked=2, asked=2)
    told.clear()
    feed(sender, "Error:checksum mismatch")
    assert told == [None]
    sender.stop(StreamCancelled("test over"))
    with pytest.raises(StreamCancelled):
        await asyncio.wait_for(done, 1)


async def test_the_watchdog_sleeps_between_looks_when_nudges_are_off() -> None:
    """With nudges off the watchdog ticks every 50 ms; a tick of 0 would spin the event loop and
    take a core of the printer's host for as long as a line is in flight."""
    sender, wire = make(timeouts=Timeouts(nudge_s=0, default_s=30))
    sender.start()
    done = sender.stream(program(1))
    cpu = time.process_time()
    await asyncio.sleep(0.5)
    assert time.process_time() - cpu < 0.05
    feed(sender, "ok")
    await asyncio.wait_for(done, 1)
    sender.stop(StreamCancelled("test over"))
