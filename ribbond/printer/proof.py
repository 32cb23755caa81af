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

The same report proves a line on firmware whose plain ``ok`` names no line (:func:`expected_position`):
a line the printer asked for again and then never acknowledged may have been marked received without
running (a firmware that times out after a resend request), or only its ``ok`` was lost. With nothing
after it sent, ``M400`` + ``M114`` tells which, for a move: the printer is where the program is after
that line, or where it was before it.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Sequence
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


# ---------------------------------------------------------------------- a re-sent line's position

#: Half the resolution of ``M114``'s report (Marlin prints two decimals) plus float rounding: a
#: reported axis within this of the program's position is at it.
POSITION_TOLERANCE_MM = 0.02
#: A move proves that it ran only by moving an axis at least this far (well beyond twice the
#: tolerance, so the position before it cannot pass for the position after it).
MIN_PROOF_MOVE_MM = 0.1

_AXES = ("X", "Y", "Z")
_MOVE_WORDS = ("G0", "G1", "G2", "G3")
_VALUE = re.compile(r"([XYZ])\s*([-+]?(?:\d+\.?\d*|\.\d+))", re.IGNORECASE)


_WORD = re.compile(r"^\s*([GMT])0*(\d+)", re.IGNORECASE)


def _command_word(command: str) -> str:
    """``G1`` for ``G1 X1``, ``G01X1`` and ``g1 x1``; "" for a line without a command word."""
    match = _WORD.match(command)
    return f"{match.group(1).upper()}{match.group(2)}" if match else ""


def _axis_values(command: str) -> dict[str, float]:
    match = _WORD.match(command)
    rest = command[match.end():] if match else ""
    return {axis.upper(): float(value) for axis, value in _VALUE.findall(rest)}


def _step(position: dict[str, float | None], relative: bool, command: str) -> bool:
    """Apply one command to ``position`` (X, Y, Z; None where unknown); returns the new
    ``relative`` mode. Only what the program itself makes known is known: a homing, a probing or
    a ``G92`` without axes makes axes unknown (where they end depends on the machine)."""
    word = _command_word(command)
    values = _axis_values(command)
    if word == "G90":
        return False
    if word == "G91":
        return True
    if word in _MOVE_WORDS:
        for axis, value in values.items():
            if not relative:
                position[axis] = value
            else:
                old = position[axis]
                position[axis] = None if old is None else old + value
    elif word == "G92":
        for axis in _AXES:
            if not values or axis in values:
                position[axis] = values.get(axis)
    elif word == "G28":
        match = _WORD.match(command)
        named = {axis for axis in _AXES if axis in command[match.end():].upper()} if match else set()
        for axis in _AXES:
            if not named or axis in named:  # G28 X homes X alone (its letters carry no value)
                position[axis] = None
    elif word in ("G29", "G30", "G33", "G34", "M48", "G53", "G54", "G55", "G56", "G57", "G58", "G59"):
        for axis in _AXES:
            position[axis] = None
    return relative


def expected_position(commands: Sequence[str], index: int) -> dict[str, float] | None:
    """The position (``M114``'s X, Y, Z) the program has once line ``index`` has run, on the axes
    the program makes known; None when that position cannot prove that the line ran: it is not a
    move, or it moves no known axis by ``MIN_PROOF_MOVE_MM`` (then the position before it would
    look the same).

    After ``M400`` the printer is where the last line it ran left it; with nothing after line
    ``index`` sent, that position is the one after ``index`` if it ran, the one before if not.
    The program starts in absolute positioning with every axis unknown (a program's first
    absolute move makes its axes known)."""
    if not 0 <= index < len(commands):
        raise ValueError(f"line index {index} outside the program's {len(commands)} lines")
    position: dict[str, float | None] = dict.fromkeys(_AXES)
    relative = False
    for command in commands[:index]:
        relative = _step(position, relative, command)
    before = dict(position)
    if _command_word(commands[index]) not in _MOVE_WORDS:
        return None
    _step(position, relative, commands[index])
    after = {axis: value for axis, value in position.items() if value is not None}
    moved = any(before[axis] is not None and abs(value - before[axis]) >= MIN_PROOF_MOVE_MM
                for axis, value in after.items())
    return after if moved else None


def at_position(report: tuple[float, float, float], expected: dict[str, float]) -> bool:
    """Whether a reported (x, y, z) is at ``expected`` on every axis it gives."""
    reported = dict(zip(_AXES, report))
    return all(abs(reported[axis] - value) <= POSITION_TOLERANCE_MM for axis, value in expected.items())
