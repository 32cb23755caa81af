"""The resend hold when the printer asks for a later line during it (issue 35, the mutation run's
survivors): the target moves to the latest line asked for, and the hold ends as soon as each line
sent after the new target has drawn its request (Marlin answers each stale line with one), or at
once when no line was sent after it, without waiting for the settle time (10 s here)."""

from __future__ import annotations

import asyncio

import pytest

from ribbond.printer.errors import LinkError
from ribbond.printer.sender import Timeouts

from .test_sender import feed, make, program

SLOW = Timeouts(resend_settle_s=10)


def holding() -> tuple:
    """Lines 0-4 out (ADVANCED_OK, a queue of 4), line 0 acknowledged, line 1 asked for: holding."""
    sender, wire = make(rx=4096, timeouts=SLOW)
    done = sender.stream(program(12))
    feed(sender, "ok N0 P15 B3")
    assert wire.numbers() == [0, 1, 2, 3, 4]
    feed(sender, "Resend: 1", "ok")
    return sender, wire, done


async def test_a_later_target_ends_the_hold_once_its_stale_lines_have_drawn_their_requests() -> None:
    sender, wire, done = holding()
    feed(sender, "Resend: 2", "ok")                     # lines 3 and 4 were sent after it
    feed(sender, "Resend: 2", "ok")
    assert wire.numbers() == [0, 1, 2, 3, 4], "a stale line may still be on its way"
    feed(sender, "Resend: 2", "ok")
    # (line 1 left the count in flight with the first request: four slots for 2-5)
    assert wire.numbers()[5:] == [2, 3, 4, 5], "the resend goes out at once, from the new target"
    line = 1
    while not done.done():
        feed(sender, f"ok N{line} P15 B3")
        line += 1
        await asyncio.sleep(0)
    assert done.result().lines == 12 and done.result().resends == 1


async def test_a_later_target_with_nothing_sent_after_it_is_resent_at_once() -> None:
    sender, wire, done = holding()
    feed(sender, "Resend: 4", "ok")                     # the last line sent: no stale line after it
    assert wire.numbers()[5:] == [4, 5, 6, 7]
    done.cancel()


async def test_stop_during_a_moved_hold_cancels_its_timer() -> None:
    sender, wire, done = holding()
    feed(sender, "Resend: 2", "ok")
    sender.stop(LinkError("closed"))
    with pytest.raises(LinkError, match="closed"):
        await asyncio.wait_for(done, 1)
    assert wire.numbers() == [0, 1, 2, 3, 4]
