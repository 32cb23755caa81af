"""G-code text helpers written after Marlin's parser: checksum, strtol, words.

Deliberately independent of any host-side code: the simulator plays firmware
written by someone else.
"""

from __future__ import annotations

import operator
import re
from dataclasses import dataclass, field
from functools import reduce

__all__ = ["checksum", "strtol", "strip_line_number", "GCode", "parse"]

_INT = re.compile(r"\s*([-+]?\d+)")
_LINE_NUMBER = re.compile(r"N[-+]?\d*\s*")
_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))?")
_COMMAND = re.compile(r"([GMT])\s*(\d+)(?:\.\d+)?")


def checksum(data: bytes) -> int:
    """XOR of every byte (Marlin's and RepRap's line checksum)."""
    return reduce(operator.xor, data, 0)


def strtol(text: str, start: int = 0) -> int:
    """C ``strtol(text + start, NULL, 10)``: leading integer, or 0 if none."""
    m = _INT.match(text, start)
    return int(m.group(1)) if m else 0


def strip_line_number(line: str) -> str:
    """The command as the parser sees it: no ``N<line>`` prefix, no ``*checksum``."""
    if line.startswith("N"):
        m = _LINE_NUMBER.match(line)
        if m:
            line = line[m.end():]
    star = line.find("*")
    if star >= 0:
        line = line[:star]
    return line.strip()


@dataclass
class GCode:
    """A parsed command: its code (``G1``, ``M105``, ``T0``) and parameter words."""

    code: str
    params: dict[str, float | None] = field(default_factory=dict)
    text: str = ""
    """The raw text after the code (for M117/M118 strings)."""

    def has(self, letter: str) -> bool:
        return letter in self.params

    def value(self, letter: str, default: float | None = None) -> float | None:
        """The letter's number; ``default`` if absent or given without a number."""
        v = self.params.get(letter)
        return default if v is None else v


def parse(command: str) -> GCode | None:
    """Parse a stripped command; None if it does not start with G, M or T<number>."""
    upper = command.upper()
    m = _COMMAND.match(upper)
    if not m:
        return None
    code = m.group(1) + str(int(m.group(2)))
    rest = upper[m.end():]
    params: dict[str, float | None] = {}
    for letter, number in _WORD.findall(rest):
        params[letter] = float(number) if number else None
    return GCode(code, params, command[m.end():].strip())
