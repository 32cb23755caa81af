"""The sender's silence limits per command and its line-number reset (the handshake), in process:
what the mutation run found no fast test for (issue 35). Expectations from Marlin's commands: G4 dwells
S seconds plus P milliseconds, M0/M1 wait for the user, heating waits and motion waits are long."""

from __future__ import annotations

import asyncio

import pytest

from ribbond.printer import codec
from ribbond.printer.capabilities import Capabilities
from ribbond.printer.errors import LinkError
from ribbond.printer.sender import Sender, Timeouts

T = Timeouts(default_s=2.0, motion_wait_s=30.0, heating_s=600.0)


@pytest.mark.parametrize(("command", "seconds"), [
    ("M0", None), ("m1 press the button", None),
    *[(word, 600.0) for word in ("M109 S220", "M190 S60", "M191 S40", "M116", "M303 E0 S200 C3")],
    *[(word, 30.0) for word in ("G28", "G29", "G30", "G33", "G34", "M400", "M48", "g28 x")],
    ("G4 S3", 5.0), ("G4 P1500", 3.5), ("G4 S1.5 P250", 3.75), ("G4", 2.0), ("G4 X5", 2.0),
    ("G1 X10", 2.0), ("M105", 2.0), ("", 2.0), ("; comment", 2.0),
])
def test_the_silence_allowed_follows_the_command(command: str, seconds: float | None) -> None:
    got = T.for_command(command)
    assert got == (None if seconds is None else pytest.approx(seconds))


class Wire:
    def __init__(self) -> None:
        self.lines: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.lines.append(data)


async def test_a_reset_sends_m110_as_line_0_and_numbers_from_1() -> None:
    wire = Wire()
    sender = Sender(wire.write, Capabilities(rx_buffer_bytes=127))
    reset = sender.reset_line_numbers()
    assert wire.lines == [codec.encode(0, "M110 N0")]
    sender.handle(codec.parse_line("ok"))
    await asyncio.wait_for(reset, 1)
    answer = sender.send("M105")
    assert wire.lines[-1] == codec.encode(1, "M105")
    sender.handle(codec.parse_line("ok T:20.0 /0.0"))
    await asyncio.wait_for(answer, 1)
    again = sender.reset_line_numbers()                     # a second handshake numbers from 0 again
    assert wire.lines[-1] == codec.encode(0, "M110 N0")
    sender.handle(codec.parse_line("ok"))
    await asyncio.wait_for(again, 1)
    sender.send("M105")
    assert wire.lines[-1] == codec.encode(1, "M105")


async def test_no_reset_while_commands_are_outstanding() -> None:
    wire = Wire()
    sender = Sender(wire.write, Capabilities(rx_buffer_bytes=127))
    pending = sender.send("M105")
    with pytest.raises(LinkError, match="cannot reset line numbers while commands are outstanding"):
        sender.reset_line_numbers()
    sender.handle(codec.parse_line("ok T:20.0 /0.0"))
    await asyncio.wait_for(pending, 1)
    sender.reset_line_numbers()
