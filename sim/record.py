"""What the simulated printer did: executed commands and deposited segments.

The firmware appends from the simulator's loop thread; tests read snapshots from
any thread, so both lists live behind one lock.
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass
from typing import IO

__all__ = ["CommandRecord", "Segment", "Recorder"]


@dataclass(frozen=True)
class CommandRecord:
    """One executed command, as received without ``N<line>`` and ``*checksum``."""

    line: int | None
    command: str
    time: float
    """time.monotonic() when the firmware started executing it."""


@dataclass(frozen=True)
class Segment:
    """One extruding move, in machine and in fabric coordinates (mm)."""

    x0: float
    y0: float
    x1: float
    y1: float
    z: float
    e: float
    """Filament extruded along this segment (mm, > 0): the move's E × the M221 flow."""
    feed: float
    """Feed rate (mm/min), as run: the move's F × the M220 override."""
    time: float
    """time.monotonic() when the move finished."""
    side: str
    """Which face of the fabric was up: "front" or "back"."""
    fx0: float
    fy0: float
    fx1: float
    fy1: float


class Recorder:
    """Thread-safe log of commands and segments, optionally mirrored to a JSON-lines file."""

    def __init__(self, record_path: str | None = None) -> None:
        self._lock = threading.Lock()
        self._commands: list[CommandRecord] = []
        self._segments: list[Segment] = []
        self._file: IO[str] | None = (
            open(record_path, "w", encoding="utf-8") if record_path else None
        )

    def add_command(self, rec: CommandRecord) -> None:
        with self._lock:
            self._commands.append(rec)
            if self._file is not None:
                # Flushed per line so a crash or SIGKILL still leaves a usable log.
                self._file.write(json.dumps(
                    {"line": rec.line, "command": rec.command, "time": rec.time}) + "\n")
                self._file.flush()

    def add_segment(self, seg: Segment) -> None:
        with self._lock:
            self._segments.append(seg)

    def commands(self) -> list[CommandRecord]:
        with self._lock:
            return list(self._commands)

    def segments(self, start: int = 0) -> list[Segment]:
        """The segments from the ``start``-th on (a reader that has the first ones copies no more)."""
        with self._lock:
            return self._segments[start:]

    def close(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None
