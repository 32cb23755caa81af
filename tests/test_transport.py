"""The serial transport on a raw pty: lines in, bytes out, urgent lines at a line boundary."""

from __future__ import annotations

import asyncio
import os
import tty

from ribbond.printer.transport import SerialTransport


async def test_lines_in_and_urgent_line_at_a_boundary() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    os.close(slave)
    received: list[str] = []
    lost: list[Exception] = []
    transport = SerialTransport(port, 250000, on_line=received.append, on_lost=lost.append)
    await transport.open()
    try:
        os.write(master, b"ok N1 P15 B3\r\nstart\n\npartial")
        await asyncio.sleep(0.05)
        assert received == ["ok N1 P15 B3", "start"], "CR stripped, blank lines dropped, partial kept"
        # Pretend the OS took only part of a line: the rest waits in the transport's queue.
        transport._tx.extend(b"4 G1 X1*99\nN5 G1 X2*98\n")
        transport.write_urgent(b"M112\n")
        assert bytes(transport._tx) == b"4 G1 X1*99\nM112\nN5 G1 X2*98\n"
        transport._tx.clear()
        os.close(master)  # the printer goes away
        await asyncio.sleep(0.05)
        assert len(lost) == 1 and not transport.is_open
    finally:
        transport.close()
