"""The printer as the daemon's components reach it: the link (and why it cannot be used now), one
sequence of moves at a time, and where the head was commanded to.

The commanded position is exact where ``M114`` reports it rounded to 10 µm; it holds only on the
connection it was commanded through (a reconnect, a homing or typed G-code forget it).
"""

from __future__ import annotations

import asyncio

from ribbond.printer.errors import LinkError, PrinterHalted
from ribbond.printer.link import LinkState, PrinterLink


AXES = ("x", "y", "z")


def homed_after(commands: list[str], homed: frozenset[str]) -> frozenset[str]:
    """The axes homed after ``commands`` ran from ``homed``: ``G28`` homes the axes it names (all
    when it names none); ``M84``/``M18`` switch the motors of the axes they name off (all when
    none), and an axis whose motor was off is no longer where the firmware thinks (Marlin 2 then
    asks to home it again)."""
    for command in commands:
        words = command.split(";", 1)[0].upper().split()
        if not words:
            continue
        named = frozenset(a for a in AXES if any(w[0] == a.upper() for w in words[1:]))
        if words[0] == "G28":
            homed = homed | (named or frozenset(AXES))
        elif words[0] in ("M84", "M18"):
            homed = homed - (named or frozenset(AXES))
    return homed


class Head:
    """The link (None: no printer), the lock of the head's moves and its commanded position."""

    def __init__(self, link: PrinterLink | None) -> None:
        self.link = link
        self.lock = asyncio.Lock()       # one sequence of moves at a time (manual, marks, pause)
        self._xyz: tuple[float, float, float] | None = None    # commanded position (exact)
        self._sender: object = None      # the link's sender the position was commanded through
        self._homed: frozenset[str] = frozenset()    # axes homed through this daemon on _homed_on
        self._homed_on: object = None    # the link's sender (the connection) they were homed on

    def require_link(self) -> PrinterLink:
        """The link, or ``LinkError`` saying why it cannot be used now."""
        if self.link is None or self.link.state is LinkState.DISCONNECTED:
            raise LinkError("the printer is not connected")
        if self.link.state is LinkState.HALTED:
            raise PrinterHalted("the printer is halted (emergency stop or a firmware error): ribbonctl recover")
        if self.link.state is LinkState.CONNECTING:
            raise LinkError("the printer is connecting; try again in a moment")
        return self.link

    def connected(self) -> bool:
        """The printer is connected and idle (no program streaming)."""
        return self.link is not None and self.link.state is LinkState.READY

    @property
    def position(self) -> tuple[float, float, float] | None:
        """The commanded position, if known."""
        return self._xyz

    def commanded(self, link: PrinterLink) -> tuple[float, float, float] | None:
        """The commanded position if it holds on ``link``'s connection (None: not known without
        asking the printer)."""
        return self._xyz if self._xyz is not None and self._sender is link.sender else None

    def set(self, xyz: tuple[float, float, float]) -> None:
        """The head was commanded to ``xyz`` (and the move finished)."""
        self._xyz = xyz
        self._sender = self.link.sender if self.link is not None else None

    def forget(self) -> None:
        """The position is no longer the one commanded (homed, a program, typed G-code, a halt)."""
        self._xyz = None

    def homed(self) -> list[str]:
        """The axes homed on the current connection (``x``, ``y``, ``z``), as far as the daemon saw:
        none after a (re)connect or a halt, until a ``G28``; an axis whose motor was switched off
        is no longer homed."""
        sender = self._connection()
        return [a for a in AXES if a in self._homed] if sender is not None and sender is self._homed_on else []

    def ran(self, commands: list[str]) -> None:
        """``commands`` ran on the printer: the axes homed after them (``homed_after``)."""
        sender = self._connection()
        before = self._homed if sender is self._homed_on else frozenset()
        self._homed, self._homed_on = homed_after(commands, before), sender

    def _connection(self) -> object:
        """The link's sender (one per connection), None when not connected."""
        try:
            return self.link.sender if self.link is not None else None
        except LinkError:
            return None

    def unhome(self) -> None:
        """The printer lost its position (a halt, a recovery): no axis is homed."""
        self._homed = frozenset()
        self.forget()

    async def where(self, link: PrinterLink) -> tuple[float, float, float]:
        """The head's commanded position, else (first time, after homing, after typed G-code, after a
        reconnect) the printer's own (``M400``, ``M114``)."""
        if self._xyz is not None and self._sender is link.sender:
            return self._xyz
        await link.send("M400", timeout=300)
        pos = await link.query_position()
        self.set((pos.x, pos.y, pos.z))
        assert self._xyz is not None
        return self._xyz
