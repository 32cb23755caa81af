"""The sender on other firmwares' scripted answers (issue 27, item 1): each scenario is what that
firmware prints in that situation, from its source (see tests/test_codec_dialects.py for the lines'
sources): Repetier's ``skip`` and ``wait`` and its acknowledgement on receipt, Smoothieware's answer
to an empty line, RepRapFirmware dropping a bad line without a word."""

from __future__ import annotations

import asyncio

import pytest

from ribbond.printer.capabilities import Capabilities
from ribbond.printer.errors import ProtocolError
from ribbond.printer.sender import Sender, Timeouts

from .test_sender import Wire, feed, program


def make(dialect: str, **kwargs: object) -> tuple[Sender, Wire]:
    wire = Wire()
    caps = Capabilities(rx_buffer_bytes=4096)
    caps.use_dialect(dialect)  # type: ignore[arg-type]
    return Sender(wire.write, caps, **kwargs), wire  # type: ignore[arg-type]


async def test_repetier_skips_end_the_resend_hold_and_their_oks_acknowledge_nothing() -> None:
    """Line 0 acknowledged, lines 1-4 in flight; line 1 fails its checksum: Repetier answers the
    error, an empty line, ``Resend:1`` and ``ok``, then ``skip N``/``ok`` for each stale line (its
    waitingForResend). The sender resends from 1 as soon as every stale line has answered, and no
    ok of those counted as an acknowledgement."""
    sender, wire = make("repetier", timeouts=Timeouts(resend_settle_s=5.0))   # only the skips end the hold
    done = sender.stream(program(6))
    feed(sender, "ok 0")
    assert wire.numbers() == [0, 1, 2, 3, 4]
    feed(sender, "Error:Wrong checksum", "", "Resend:1", "ok", "skip 2", "ok", "skip 3", "ok")
    assert wire.numbers() == [0, 1, 2, 3, 4], "a stale line has not answered yet: still holding"
    feed(sender, "skip 4")
    assert wire.numbers()[5:] == [1, 2, 3, 4], "resent from line 1 once every stale line answered"
    feed(sender, "ok")
    assert sender.last_acknowledged_line == 0, "the oks after Resend and skip acknowledged nothing"
    feed(sender, "ok 1", "ok 2", "ok 3", "ok 4")
    assert wire.numbers()[-1] == 5
    feed(sender, "ok 5")
    assert (await asyncio.wait_for(done, 1)).lines == 6


async def test_repetier_wait_probes_lines_left_unacknowledged_at_once() -> None:
    """``wait``: Repetier's buffer has been empty for a second; a line still unacknowledged lost
    its ok (or itself): a numbered M105 goes out now, not after the silence timeout."""
    sender, wire = make("repetier", timeouts=Timeouts(default_s=60))
    done = sender.stream(program(2))
    feed(sender, "ok 0")
    feed(sender, "wait")
    assert wire.lines[-1] == (2, "M105"), wire.lines
    feed(sender, "ok 2", "T:25.00 /0 B:25.00 /0 B@:0 @:0")      # the probe's ok: line 1 was received
    assert (await asyncio.wait_for(done, 1)).lines == 2


async def test_repetier_an_m400s_answer_waits_for_the_proof_that_it_ran() -> None:
    """Repetier acknowledges ``M400`` on receipt (``ok 0``) and starts it; only the report of the
    ``M114`` sent right behind it (printed when that runs, so after the moves) proves it done."""
    sender, wire = make("repetier")
    answer = sender.send("M400")
    assert wire.lines == [(0, "M400"), (1, "M114")]
    feed(sender, "ok 0", "ok 1", "busy:processing")
    await asyncio.sleep(0)
    assert not answer.done(), "received is not run"
    feed(sender, "X:10.00 Y:20.00 Z:0.300 E:0.0000")
    assert (await asyncio.wait_for(answer, 1)).command == "M400"


async def test_repetier_a_programs_m400_counts_once_proven_and_holds_the_next_lines() -> None:
    """A part's M400 in a program: its proof M114 follows it, the next program line waits, and the
    M400 is not counted acknowledged (the part not printed) before the report; ``wait`` proves too."""
    sender, wire = make("repetier")
    seen: list[int] = []
    done = sender.stream(["G1 X1", "M400", "G1 X2"], progress=lambda p: seen.append(p.acknowledged))
    assert wire.lines == [(0, "G1 X1"), (1, "M400"), (2, "M114")]
    feed(sender, "ok 0", "ok 1", "ok 2")
    assert wire.lines[-1] == (2, "M114") and seen[-1] == 1, "M400 received, not proven: G1 X2 waits"
    feed(sender, "wait")                                         # its buffer emptied: all ran
    assert seen[-1] == 2 and wire.lines[-1] == (3, "G1 X2")
    feed(sender, "ok 3")
    assert (await asyncio.wait_for(done, 1)).lines == 3


@pytest.mark.parametrize("dialect, nudges", [("marlin2", True), ("smoothieware", False)])
async def test_a_firmware_that_answers_empty_lines_is_never_nudged(dialect: str, nudges: bool) -> None:
    """Smoothieware answers an empty line with ``ok`` (GcodeDispatch.cpp), which would acknowledge
    a line that has not run: no bare newline is ever sent to it; Marlin ignores one."""
    sender, wire = make(dialect, timeouts=Timeouts(nudge_s=0.02))
    sender.start()
    done = sender.stream(program(1))
    await asyncio.sleep(0.2)
    assert (wire.nudges > 0) == nudges
    feed(sender, "ok")
    await asyncio.wait_for(done, 1)
    sender.stop(ProtocolError("test over"))


async def test_reprapfirmware_a_dropped_line_stops_before_its_parts_m400_counts() -> None:
    """RepRapFirmware 3 drops a line with a bad checksum without a word and answers the others with
    plain oks, so they seem to acknowledge the dropped one. An M105 follows each M400: its ``ok T:…``
    names its line, shows that one ok is missing, and the stream stops before the M400 (the part's
    end) counts."""
    sender, wire = make("reprapfirmware")
    seen: list[int] = []
    done = sender.stream(["G1 X1", "G1 X2", "M400", "G1 X3"], progress=lambda p: seen.append(p.acknowledged))
    assert wire.lines[:4] == [(0, "G1 X1"), (1, "G1 X2"), (2, "M400"), (3, "M105")]
    feed(sender, "ok", "ok")                                     # line 1 was dropped: the M400's ok
    feed(sender, "ok T:25.0 /0.0 T0:25.0 /0.0 B:25.0 /0.0")      # the M105's answer
    with pytest.raises(ProtocolError, match=r"lines 0 to 2 may never have run"):
        await asyncio.wait_for(done, 1)
    assert max(seen) < 3, "the M400 (program line 3) never counted"


async def test_reprapfirmware_nothing_dropped_streams_on() -> None:
    sender, wire = make("reprapfirmware")
    done = sender.stream(["G1 X1", "M400", "G1 X2"])
    feed(sender, "ok", "ok", "ok T:25.0 /0.0 T0:25.0 /0.0 B:25.0 /0.0", "ok")
    assert (await asyncio.wait_for(done, 1)).lines == 3
    assert [c for _, c in wire.lines] == ["G1 X1", "M400", "M105", "G1 X2"]
