"""The pseudo-terminal a host opens, and the byte pacing of a real serial line.

A pty moves bytes instantly, so both directions are paced here as 8N1 at the
configured baud: a byte takes 10/baud seconds.  Incoming bytes are read from the
master as soon as the kernel has them (the kernel buffer must never act as flow
control) and each gets the time it would have finished arriving on a real wire.
Outgoing lines are released to the master no faster than the wire could carry them.
All of this is chunked: nothing is scheduled per byte.
"""

from __future__ import annotations

import asyncio
import errno
import os
import select
import time
import tty
from collections import deque
from collections.abc import Callable
from typing import Protocol

__all__ = ["InputPacer", "OutputPacer", "PtyPort"]

_POLL_S = 0.02  # how often to look for the host opening the port
_MAX_UNWRITTEN = 1 << 20  # a host that stops reading cannot make us hoard forever
_MAX_PIECE = 256  # wake at least every this many bytes while a long line arrives


class InputPacer:
    """Arrival times of bytes read from the master: one byte per ``byte_time``."""

    def __init__(self, byte_time: float) -> None:
        self.byte_time = byte_time
        self._chunks: deque[list] = deque()  # [data, t0, taken]: byte k arrives at t0 + (k+1)*bt
        self._last = float("-inf")

    def push(self, data: bytes, t_read: float) -> None:
        if not data:
            return
        t0 = max(t_read, self._last)
        self._chunks.append([data, t0, 0])
        self._last = t0 + len(data) * self.byte_time

    def pending(self) -> int:
        return sum(len(c[0]) - c[2] for c in self._chunks)

    def clear(self) -> None:
        self._chunks.clear()
        self._last = float("-inf")

    def take(self, now: float) -> list[tuple[bytes, float]]:
        """Bytes arrived by ``now``, cut after each newline, with their arrival times."""
        out: list[tuple[bytes, float]] = []
        bt = self.byte_time
        while self._chunks:
            chunk = self._chunks[0]
            data, t0, taken = chunk
            arrived = min(len(data), int((now - t0) / bt + 1e-6))
            pos = taken
            while pos < arrived:
                nl = data.find(b"\n", pos, arrived)
                end = arrived if nl < 0 else nl + 1
                out.append((data[pos:end], t0 + end * bt))
                pos = end
            if arrived < len(data):
                chunk[2] = max(taken, arrived)
                break
            self._chunks.popleft()
        return out

    def next_event(self) -> float | None:
        """When the next newline (or a long stretch without one) will have arrived."""
        if not self._chunks:
            return None
        data, t0, taken = self._chunks[0]
        nl = data.find(b"\n", taken)
        end = len(data) if nl < 0 else nl + 1
        end = min(end, taken + _MAX_PIECE)
        return t0 + end * self.byte_time


class OutputPacer:
    """Releases whole lines once the wire would have carried their last byte."""

    def __init__(self, byte_time: float) -> None:
        self.byte_time = byte_time
        self._lines: deque[tuple[float, bytes]] = deque()
        self._free = float("-inf")

    def push(self, data: bytes, ready: float) -> None:
        # Lines leave in order: a held-back line holds back the ones after it.
        start = max(ready, self._free)
        self._free = start + len(data) * self.byte_time
        self._lines.append((self._free, data))

    def take(self, now: float) -> bytes:
        out = []
        while self._lines and self._lines[0][0] <= now:
            out.append(self._lines.popleft()[1])
        return b"".join(out)

    def next_event(self) -> float | None:
        return self._lines[0][0] if self._lines else None

    def pending(self) -> int:
        return len(self._lines)

    def clear(self) -> None:
        self._lines.clear()
        self._free = float("-inf")


class _ByteCounters(Protocol):
    bytes_in: int
    bytes_out: int


class PtyPort:
    """The master side of a pty whose slave path the host opens.

    The slave is put in raw mode once and closed here: only then does the master
    see POLLHUP while no host has the port open, which is how opening and closing
    are detected.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, byte_time: float, counters: _ByteCounters,
                 *, on_read: Callable[[bytes, float], bytes],
                 on_open: Callable[[float], None], on_close: Callable[[float], None],
                 on_activity: Callable[[], None]) -> None:
        self._loop = loop
        self._counters = counters
        self._on_read = on_read
        self._on_open = on_open
        self._on_close = on_close
        self._on_activity = on_activity
        self.input = InputPacer(byte_time)
        self.output = OutputPacer(byte_time)
        self.path: str | None = None
        self.connected = False
        self._master: int | None = None
        self._poller: select.poll | None = None
        self._poll_handle: asyncio.TimerHandle | None = None
        self._unwritten = bytearray()
        self._writing = False

    @property
    def is_open(self) -> bool:
        return self._master is not None

    def open(self) -> str:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line editing, no CR/LF translation
        self.path = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(master, False)
        self._master = master
        self._poller = select.poll()
        self._poller.register(master, 0)  # POLLHUP is reported whatever the mask
        self._poll_host()
        return self.path

    def close(self) -> None:
        """Unplug: the host's reads fail with EIO and the device path disappears."""
        if self._poll_handle is not None:
            self._poll_handle.cancel()
            self._poll_handle = None
        if self._master is None:
            return
        if self.connected:
            self._loop.remove_reader(self._master)
        if self._writing:
            self._loop.remove_writer(self._master)
            self._writing = False
        os.close(self._master)
        self._master = None
        self._poller = None
        was_connected = self.connected
        self.connected = False
        self._drop_buffers()
        if was_connected:
            self._on_close(time.monotonic())

    def _drop_buffers(self) -> None:
        self.input.clear()
        self.output.clear()
        self._unwritten.clear()

    # --- host open / close -----------------------------------------------------------

    def _poll_host(self) -> None:
        self._poll_handle = None
        if self._master is None or self._poller is None:
            return
        hup = any(ev & (select.POLLHUP | select.POLLERR) for _, ev in self._poller.poll(0))
        if hup:
            self._poll_handle = self._loop.call_later(_POLL_S, self._poll_host)
            return
        self.connected = True
        self._loop.add_reader(self._master, self._readable)
        self._on_open(time.monotonic())

    def _hangup(self) -> None:
        assert self._master is not None
        self._loop.remove_reader(self._master)
        if self._writing:
            self._loop.remove_writer(self._master)
            self._writing = False
        self.connected = False
        self._drop_buffers()
        self._on_close(time.monotonic())
        self._poll_handle = self._loop.call_later(_POLL_S, self._poll_host)

    # --- reading ---------------------------------------------------------------------

    def _readable(self) -> None:
        if self._master is None:
            return
        got = False
        for _ in range(16):
            try:
                data = os.read(self._master, 65536)
            except BlockingIOError:
                break
            except OSError as exc:
                if exc.errno != errno.EIO:
                    raise
                data = b""
            if not data:  # EIO: the host closed the slave
                self._hangup()
                return
            self._counters.bytes_in += len(data)
            now = time.monotonic()
            self.input.push(self._on_read(data, now), now)
            got = True
        if got:
            self._on_activity()

    # --- writing ---------------------------------------------------------------------

    def send(self, data: bytes, ready: float) -> None:
        """Queue a line for the host; lost if nobody has the port open (as on a board)."""
        if self.connected:
            self.output.push(data, ready)

    def flush(self, now: float) -> None:
        data = self.output.take(now)
        if data and self.connected:
            self._write(data)

    def _write(self, data: bytes) -> None:
        if self._unwritten:
            if len(self._unwritten) < _MAX_UNWRITTEN:
                self._unwritten += data
            return
        assert self._master is not None
        try:
            n = os.write(self._master, data)
        except BlockingIOError:
            n = 0
        except OSError:
            return  # the host vanished; the reader will notice the hangup
        self._counters.bytes_out += n
        if n < len(data):
            self._unwritten += data[n:]
            self._loop.add_writer(self._master, self._writable)
            self._writing = True

    def _writable(self) -> None:
        assert self._master is not None
        try:
            n = os.write(self._master, self._unwritten)
        except BlockingIOError:
            return
        except OSError:
            n = len(self._unwritten)
        else:
            self._counters.bytes_out += n
        del self._unwritten[:n]
        if not self._unwritten:
            self._loop.remove_writer(self._master)
            self._writing = False
