"""A bare-bones host for the simulator's own tests (standard library only).

It opens the pty slave like any host would, writes raw or numbered lines and reads
replies with timeouts.  It is deliberately dumb: no flow control, no resends.
"""

from __future__ import annotations

import errno
import os
import select
import time
from collections.abc import Iterator
from contextlib import contextmanager
from functools import reduce

from .config import SimConfig
from .printer import SimulatedPrinter

__all__ = ["PtyHost", "numbered", "connected"]


def numbered(n: int, command: str) -> bytes:
    """``N<n> <command>*<checksum>\\n`` as a RepRap host sends it."""
    body = f"N{n} {command}"
    cs = reduce(lambda a, b: a ^ b, body.encode(), 0)
    return f"{body}*{cs}\n".encode()


class PtyHost:
    def __init__(self, path: str) -> None:
        self.fd: int | None = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self._buf = bytearray()
        self.log: list[tuple[float, str]] = []  # every line read, with its read time

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> PtyHost:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def write(self, data: bytes | str) -> float:
        """Write everything; return the time.monotonic() of the write."""
        if isinstance(data, str):
            data = data.encode()
        assert self.fd is not None
        t = time.monotonic()
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
            except BlockingIOError:
                select.select([], [self.fd], [], 0.05)
                continue
            view = view[n:]
        return t

    def send(self, command: str, n: int | None = None) -> float:
        return self.write(numbered(n, command) if n is not None else (command + "\n").encode())

    def _fill(self, timeout: float) -> None:
        assert self.fd is not None
        r, _, _ = select.select([self.fd], [], [], max(0.0, timeout))
        if r:
            data = os.read(self.fd, 65536)
            if not data:
                # Linux: a hung-up tty reads as end of file (writes fail with EIO).
                raise OSError(errno.EIO, "pty hung up: the simulator closed its side")
            self._buf += data

    def readline(self, timeout: float = 2.0) -> str | None:
        """The next line without its newline, or None on timeout."""
        deadline = time.monotonic() + timeout
        while True:
            i = self._buf.find(b"\n")
            if i >= 0:
                line = self._buf[:i].decode("latin-1")
                del self._buf[:i + 1]
                self.log.append((time.monotonic(), line))
                return line
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self._fill(left)

    def read_until(self, predicate, timeout: float = 2.0) -> list[str]:
        """Lines up to and including the first one matching; AssertionError on timeout."""
        deadline = time.monotonic() + timeout
        lines: list[str] = []
        while True:
            line = self.readline(max(0.0, deadline - time.monotonic()))
            if line is None:
                raise AssertionError(f"timed out; got {lines!r}")
            lines.append(line)
            if predicate(line):
                return lines

    def read_quiet(self, quiet: float = 0.15, timeout: float = 5.0) -> list[str]:
        """Every line until nothing arrives for ``quiet`` seconds."""
        deadline = time.monotonic() + timeout
        lines: list[str] = []
        while time.monotonic() < deadline:
            line = self.readline(quiet)
            if line is None:
                break
            lines.append(line)
        return lines

    def read_for(self, seconds: float) -> list[str]:
        """Every line that arrives within ``seconds``."""
        deadline = time.monotonic() + seconds
        lines: list[str] = []
        while (left := deadline - time.monotonic()) > 0:
            line = self.readline(left)
            if line is not None:
                lines.append(line)
        return lines

    def wait_banner(self, timeout: float = 2.0) -> list[str]:
        """Read the boot banner (through its last settings line)."""
        lines = self.read_until(lambda s: s == "start", timeout)
        lines += self.read_until(lambda s: s.startswith("echo:  M203"), timeout)
        return lines

    def command(self, command: str, n: int | None = None, timeout: float = 2.0) -> list[str]:
        """Send one command and read through its ``ok``."""
        self.send(command, n)
        return self.read_until(lambda s: s.startswith("ok"), timeout)


@contextmanager
def connected(config: SimConfig | None = None, *, banner: bool = True,
              **printer_kwargs: object) -> Iterator[tuple[SimulatedPrinter, PtyHost]]:
    """A running simulator with a host attached (banner already read if ``banner``)."""
    sim = SimulatedPrinter(config or SimConfig(), **printer_kwargs)  # type: ignore[arg-type]
    sim.start()
    try:
        host = PtyHost(sim.port)
        try:
            if banner:
                host.wait_banner()
            yield sim, host
        finally:
            host.close()
    finally:
        sim.stop()
