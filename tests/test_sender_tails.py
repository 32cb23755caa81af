"""Cut tails on Marlin 2.x with ADVANCED_OK across two resend episodes (the flake of
``test_link.py::test_marlin2_cut_tails_are_not_taken_for_acknowledgements[advanced-ok]``: "printer
asked to resend line 751, which it had already acknowledged").

Marlin queues the tail of a line cut by its receive-buffer flush as an unnumbered command and
answers it ``echo:Unknown command`` + an ``ok`` without ``N`` when the tail reaches the head of its
queue: after the lines accepted before the flush, before the line asked for, which is sent again
later. A request for line M says every line before M was accepted, and M was not; so until M's own
``ok N<M>`` comes, no unnumbered ``ok`` may acknowledge M, also once an earlier request's line
has been acknowledged."""

from __future__ import annotations

import asyncio

import pytest

from ribbond.printer.errors import ProtocolError
from ribbond.printer.sender import Timeouts

from .test_sender import ack_numbered_from, feed, make, program

STALE = "Error:Line Number is not Last Line Number+1, Last Line: {}"


async def test_a_tail_after_the_earlier_requests_line_is_acknowledged_does_not_acknowledge_the_later() -> None:
    sender, wire = make(rx=4096, timeouts=Timeouts(resend_settle_s=0.01))
    done = sender.stream(program(12))
    feed(sender, "ok N0 P15 B3")                  # ADVANCED_OK learned; a queue of 4: lines 1-4 out
    assert wire.numbers() == [0, 1, 2, 3, 4]
    # Episode 1: line 1 corrupted; lines 2-4 refused, one request each; then 1-4 go again.
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    for _ in range(3):
        feed(sender, STALE.format(0), "Resend: 1", "ok")
    assert wire.numbers()[5:] == [1, 2, 3, 4]
    # Episode 2: the re-sent 1 is accepted, the re-sent 2 corrupted (its flush cuts 3, whose tail is
    # queued behind 1), 4 refused; the request comes before 1's ok. One request for two stale
    # lines: the hold's timer (settle 10 ms + the wire time) sends 2-4 again.
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    feed(sender, STALE.format(1), "Resend: 2", "ok")
    await asyncio.sleep(0.1)
    assert wire.numbers()[9:] == [2, 3, 4]
    feed(sender, "ok N1 P15 B3")                  # line 1 ran: a slot for line 5
    assert wire.numbers()[12:] == [5]
    feed(sender, 'echo:Unknown command: "X3.5 Y3.25 F3000*85"', "ok P15 B3")   # then the tail of 3
    assert sender.last_acknowledged_line == 1, "the tail's ok acknowledged line 2, which was asked for"
    # The re-sent 2 is corrupted again: asking for it is no reset; 3-5 refused, then 2-5 again.
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    for _ in range(3):
        feed(sender, STALE.format(1), "Resend: 2", "ok")
    assert not done.done(), "the request for line 2 ended the stream"
    assert wire.numbers()[13:] == [2, 3, 4, 5]
    await ack_numbered_from(sender, done, 2, pause=0)
    assert done.result().lines == 12


async def test_a_line_asked_for_stays_pending_after_an_earlier_ones_ok_and_is_then_asked_past() -> None:
    """Three requests: 1, then 2 before 1's ok, then (after 1's ok) 4 before 2's ok. The printer
    asked past the re-sent 2: only ``ok N2`` proves it ran, so ``ok N3`` without it stops the stream
    naming line 2 (a firmware that swallowed it; Marlin prints ``ok N2`` first)."""
    sender, wire = make(rx=4096, timeouts=Timeouts(resend_settle_s=10))
    done = sender.stream(program(16))
    feed(sender, "ok N0 P15 B3")
    feed(sender, "Error:checksum mismatch, Last Line: 0", "Resend: 1", "ok")
    for _ in range(3):
        feed(sender, STALE.format(0), "Resend: 1", "ok")
    feed(sender, "Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok")
    for _ in range(2):
        feed(sender, STALE.format(1), "Resend: 2", "ok")
    assert wire.numbers()[9:] == [2, 3, 4]
    feed(sender, "ok N1 P15 B3")                  # line 1's own ok: a slot for line 5
    assert wire.numbers()[12:] == [5]
    feed(sender, "Error:checksum mismatch, Last Line: 3", "Resend: 4", "ok")
    feed(sender, STALE.format(3), "Resend: 4", "ok")
    assert wire.numbers()[13:] == [4, 5]
    feed(sender, "ok N3 P15 B3")
    with pytest.raises(ProtocolError, match=r"acknowledged line 3 but never line 2 \(program line 3: "):
        await asyncio.wait_for(done, 1)
