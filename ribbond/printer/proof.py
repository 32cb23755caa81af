"""Proof that commands have run, for firmware whose ``ok`` only says a line was received.

Repetier acknowledges a line as soon as it is in its command buffer (``gcode.cpp``,
``checkAndPushCommand``: the ``ok`` is printed right after the line is queued), not once the command
has run. The rest of ribbond counts on an acknowledged ``M400`` meaning "every move before it is
done" (a part printed, the front finished, a pause's exact checkpoint), so for such firmware a
command's answer waits for a proof that it has run. Commands run in order, so two things prove it:

* the position report of an ``M114`` received after it (printed when that ``M114`` runs), and
* a ``wait`` line: the printer has had an empty command buffer for a second.

:class:`RunProofs` keeps the lines acknowledged on receipt and not yet proven, and the ``M114`` lines
received whose report has not come, in order. It is pure bookkeeping: the sender decides which lines
need a proof, sends the ``M114`` and completes what this class says is proven.
"""

from __future__ import annotations

from collections import deque
from typing import Generic, Protocol, TypeVar


class _Numbered(Protocol):
    number: int
    command: str


L = TypeVar("L", bound=_Numbered)


def _is_position_query(command: str) -> bool:
    words = command.split()
    return bool(words) and words[0].upper() == "M114"


class RunProofs(Generic[L]):
    """The lines waiting for a proof that they have run, and the position queries that give one."""

    def __init__(self) -> None:
        self._unproven: deque[L] = deque()
        self._queries: deque[L] = deque()

    @property
    def oldest_unproven(self) -> L | None:
        """The oldest line acknowledged on receipt whose run is not proven (its output comes now)."""
        return self._unproven[0] if self._unproven else None

    def received(self, line: L, *, needs_proof: bool) -> None:
        """``line`` was acknowledged on receipt; ``needs_proof``: its answer waits for a proof."""
        if needs_proof:
            self._unproven.append(line)
        if _is_position_query(line.command):
            self._queries.append(line)

    def position_reported(self) -> list[L]:
        """A position report came: the oldest ``M114`` received has run, and every line before it.
        Returns the lines this proves, oldest first (none when no query was waiting)."""
        if not self._queries:
            return []
        return self._through(self._queries.popleft().number)

    def idle(self, received_through: int) -> list[L]:
        """``wait``: every line received (through ``received_through``) has run."""
        while self._queries and self._queries[0].number <= received_through:
            self._queries.popleft()  # their reports came before, or were lost
        return self._through(received_through)

    def clear(self) -> list[L]:
        """Forget everything (the link stopped or numbers lines again); returns the unproven lines."""
        unproven = list(self._unproven)
        self._unproven.clear()
        self._queries.clear()
        return unproven

    def _through(self, number: int) -> list[L]:
        proven: list[L] = []
        while self._unproven and self._unproven[0].number <= number:
            proven.append(self._unproven.popleft())
        return proven
