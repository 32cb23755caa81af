"""The serial port as an asyncio transport: bytes out, lines in, no threads.

pyserial opens and configures the port (baud, raw mode, an exclusive lock so two hosts cannot share
a printer); after that the file descriptor is driven by the event loop's reader and writer
callbacks. The transport knows nothing of G-code: it hands every received line to ``on_line`` and
reports a lost port once to ``on_lost``.
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import termios
from collections.abc import Callable

import serial

log = logging.getLogger(__name__)

#: A line longer than this is noise (a wrong baud rate, a board printing binary): cut it.
MAX_RECEIVED_LINE = 4096


class PortError(OSError):
    """The serial port could not be opened or was lost."""


def _lost_reason(exc: OSError) -> OSError:
    """Why the port went away, in the operator's words where the errno says it: EIO is how Linux
    reports a vanished USB device (or a closed pty master), on reads and on writes."""
    if exc.errno == errno.EIO:
        return PortError("the device is gone (unplugged or switched off)")
    return exc


class SerialTransport:
    """An open serial port driven by the running event loop.

    Parameters
    ----------
    port, baud
        Device path and baud rate.
    on_line
        Called with each received line, decoded, without its terminator.
    on_lost
        Called once when the port goes away (unplugged, the printer's USB reset, closed pty), with
        the reason.
    reset_on_open
        Pulse DTR after opening, which resets boards with an auto-reset circuit. Off by default:
        a host should not reboot the printer just by connecting.
    """

    def __init__(
        self,
        port: str,
        baud: int,
        *,
        on_line: Callable[[str], None],
        on_lost: Callable[[Exception], None],
        reset_on_open: bool = False,
    ) -> None:
        self.port = port
        self.baud = baud
        self._on_line = on_line
        self._on_lost = on_lost
        self._reset_on_open = reset_on_open
        self._serial: serial.Serial | None = None
        self._fd: int | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._rx = bytearray()
        self._tx = bytearray()
        self._lost = False
        self.bytes_out = 0
        self.bytes_in = 0

    @property
    def is_open(self) -> bool:
        return self._fd is not None and not self._lost

    async def open(self) -> None:
        """Open and configure the port and start reading."""
        self._loop = asyncio.get_running_loop()
        ser = serial.Serial()
        ser.port = self.port
        ser.baudrate = self.baud
        ser.timeout = 0
        ser.write_timeout = 0
        ser.exclusive = True
        # Leave DTR as the OS set it on open; toggling it is what resets Arduino-style boards.
        ser.dsrdtr = False
        ser.rtscts = False
        try:
            ser.open()
        except (serial.SerialException, OSError) as exc:
            raise PortError(f"cannot open serial port {self.port}: {exc}") from exc
        self._serial = ser
        self._fd = ser.fileno()
        self._keep_dtr_on_close(self._fd)
        if self._reset_on_open:
            ser.dtr = False
            await asyncio.sleep(0.1)
            ser.dtr = True
        self._loop.add_reader(self._fd, self._read_ready)

    @staticmethod
    def _keep_dtr_on_close(fd: int) -> None:
        """Clear HUPCL so that closing the port does not drop DTR, and the next open (ours or a
        restarted daemon's) does not produce the DTR edge that resets the board."""
        try:
            attrs = termios.tcgetattr(fd)
            attrs[2] &= ~termios.HUPCL
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
        except termios.error:
            pass  # not a real tty (some USB CDC drivers): nothing to keep

    def write(self, data: bytes) -> None:
        """Queue ``data`` for the port; bytes go out in order, without blocking the loop."""
        if not self.is_open:
            raise PortError(f"serial port {self.port} is not open")
        if self._tx:
            self._tx.extend(data)
            return
        sent = self._write_now(data)
        if sent < len(data):
            self._tx.extend(data[sent:])
            assert self._loop is not None and self._fd is not None
            self._loop.add_writer(self._fd, self._write_ready)

    def write_urgent(self, data: bytes) -> None:
        """Send ``data`` (whole lines) ahead of anything still queued here: an emergency stop.

        It goes in at the first line boundary: the queue may start with the rest of a line whose
        beginning is already on the wire, and a command spliced into it would not be recognised.
        Bytes already handed to the OS cannot be overtaken; the host keeps that backlog within the
        printer's receive buffer, so it is at most a few milliseconds of wire time.
        """
        if not self.is_open:
            raise PortError(f"serial port {self.port} is not open")
        if not self._tx:
            self.write(data)
            return
        boundary = self._tx.find(b"\n") + 1  # 0 when no line ends in the queue: append after it
        at = boundary if boundary > 0 else len(self._tx)
        self._tx[at:at] = data

    @property
    def pending_out(self) -> int:
        """Bytes queued here and not yet handed to the OS."""
        return len(self._tx)

    def _write_now(self, data: bytes) -> int:
        assert self._fd is not None
        try:
            sent = os.write(self._fd, data)
        except BlockingIOError:
            return 0
        except OSError as exc:
            self._lose(_lost_reason(exc))
            return len(data)
        self.bytes_out += sent
        return sent

    def _write_ready(self) -> None:
        if not self._tx or self._fd is None:
            return
        sent = self._write_now(bytes(self._tx))
        del self._tx[:sent]
        if not self._tx and self._loop is not None and self._fd is not None and not self._lost:
            self._loop.remove_writer(self._fd)

    def _read_ready(self) -> None:
        assert self._fd is not None
        try:
            data = os.read(self._fd, 65536)
        except BlockingIOError:
            return
        except OSError as exc:
            self._lose(_lost_reason(exc))
            return
        if not data:
            self._lose(PortError("the port was closed"))
            return
        self.bytes_in += len(data)
        self._rx.extend(data)
        while True:
            end = self._rx.find(b"\n")
            if end < 0:
                break
            raw = bytes(self._rx[:end])
            del self._rx[: end + 1]
            self._deliver(raw)
        if len(self._rx) > MAX_RECEIVED_LINE:
            raw = bytes(self._rx)
            self._rx.clear()
            self._deliver(raw)

    def _deliver(self, raw: bytes) -> None:
        text = raw.decode("ascii", errors="replace").rstrip("\r")
        if text.strip():
            self._on_line(text)

    def _lose(self, reason: Exception) -> None:
        if self._lost:
            return
        self._lost = True
        self._detach()
        log.debug("serial port %s lost: %r", self.port, reason)  # the link reports it, once
        self._on_lost(reason)

    def _detach(self) -> None:
        if self._loop is not None and self._fd is not None:
            self._loop.remove_reader(self._fd)
            self._loop.remove_writer(self._fd)

    def close(self) -> None:
        """Close the port. Safe to call more than once."""
        if self._fd is not None and not self._lost:
            self._detach()
        self._lost = True
        if self._serial is not None:
            try:
                self._serial.close()
            except (serial.SerialException, OSError):
                pass
        self._serial = None
        self._fd = None
        self._tx.clear()
