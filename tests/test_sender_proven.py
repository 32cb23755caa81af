"""What a re-sent line's position proof answers (plain-ok Marlin; issue 35, the mutation run's
survivors): once the report shows the silent line ran, the M114's acknowledgement counts every line
through it, and a command still unacknowledged before that line gets its answer, with an ``ok``
(the link reads ``answer.ok``: an M105 answered so is told to have no temperatures, not a crash),
and the report is the proof's, not that command's output."""

from __future__ import annotations

import asyncio

import pytest

from ribbond.printer import codec
from ribbond.printer.errors import StreamCancelled
from ribbond.printer.sender import Sender

from .test_sender import feed, make, plain_resend, program
from .test_sender_episodes import STEPS, at, silent_resend, until


async def test_a_command_before_the_silent_line_is_answered_with_an_ok_by_the_proof() -> None:
    sender, wire = silent_resend()
    sender.start()
    temperature = sender.send("M105")              # line 0, ahead of the program
    done = sender.stream(STEPS)                    # G90 is line 1, G1 X9 Y5 2, G1 X10 Y5 3
    assert wire.numbers() == [0, 1, 2, 3]
    plain_resend(sender, wire, 3)                  # 3 refused; its copy goes alone and draws no ok
    await until(wire, "M114")                      # (nor do 0-2: their oks were lost too)
    assert wire.lines[-3:] == [(3, "G1 X10 Y5"), (4, "M400"), (5, "M114")]
    assert not temperature.done()
    feed(sender, "ok", at(10), "ok")               # the M400's ok, the report at X10 Y5, the M114's ok
    answer = await asyncio.wait_for(temperature, 1)
    assert (answer.command, answer.line) == ("M105", 0)
    assert answer.first(codec.Position) is None, "the report answered the proof's M114, not the M105"
    assert isinstance(answer.ok, codec.Ok) and answer.ok.temperatures is None
    assert sender.last_acknowledged_line == 5
    done.cancel()
    sender.stop(StreamCancelled("test over"))


async def stream_all(sender: Sender, lines: int) -> int:
    """Stream ``lines`` program lines, each acknowledged by a plain ok; the lines the result counts."""
    done = sender.stream(program(lines))
    while not done.done():
        feed(sender, "ok")
        await asyncio.sleep(0)
    return done.result().lines


@pytest.mark.parametrize("history", [16, None])
async def test_the_history_keeps_the_last_lines_acknowledged_and_no_more(history: int | None) -> None:
    """The history is bounded (``history`` lines, 1024 by default): a print of a million lines
    must not keep them all. (Read from the sender's private history: the bound is not visible on
    the wire, since a request for an acknowledged line stops the stream before it is read.)"""
    size = history or 1024
    sender, wire = make(rx=4096, **({"history": history} if history else {}))
    assert (await stream_all(sender, size + 40)) == size + 40
    assert sorted(sender._history) == list(range(40, size + 40))
    reset = sender.reset_line_numbers()            # M110 N0 is line 0, the program 1 to size + 20
    feed(sender, "ok")
    await asyncio.wait_for(reset, 1)
    assert (await stream_all(sender, size + 20)) == size + 20
    assert sorted(sender._history) == list(range(21, size + 21))

