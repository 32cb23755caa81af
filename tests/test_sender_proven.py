"""What a re-sent line's position proof answers (plain-ok Marlin; issue 35, the mutation run's
survivors): once the report shows the silent line ran, the M114's acknowledgement counts every line
through it, and a command still unacknowledged before that line gets its answer, with an ``ok``
(the link reads ``answer.ok``: an M105 answered so is told to have no temperatures, not a crash)."""

from __future__ import annotations

import asyncio

from ribbond.printer import codec
from ribbond.printer.errors import StreamCancelled

from .test_sender import feed, plain_resend
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
    assert isinstance(answer.ok, codec.Ok) and answer.ok.temperatures is None
    assert sender.last_acknowledged_line == 5
    done.cancel()
    sender.stop(StreamCancelled("test over"))
