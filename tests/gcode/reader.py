"""An independent reader of Marlin G-code, used only by the tests.

It is written from the G-code/Marlin semantics, not from `ribbond.gcode` (and imports nothing from
`ribbond`), so that a misunderstanding in the writer cannot hide in the reader too.

Modelled: comments (`;`), `N<line>` prefixes and `*<checksum>` suffixes (stripped; the checksum, the XOR
of the bytes before `*`, is verified), G0/G1 with X Y Z E F, G90/G91 (which set E's mode too, as in
Marlin), M82/M83 (E alone), G92, G28, modal F, M104/M109/M140/M190, M106/M107, M0/M1 messages.
G4, G21, M18, M84, M117 and M400 are known and ignored; any other command is listed in `unknown`.

Positions are the program's coordinates (after G92 offsets), in mm. Before anything sets an axis it is
unknown, NaN; so is E until G92 sets it (G28 does not home E), which makes absolute-E extrusion before
`G92 E0` come out as NaN.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

Point = tuple[float, float, float]

#: A word's number: optional sign, digits with an optional fraction (or a bare fraction). No exponent:
#: Marlin reads "X1e2" as X1 E2.
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
#: The command at the start of a line: letter, number, optional ".subcode" (G01 is G1).
_CODE = re.compile(r"([GMT])(\d+)(?:\.(\d+)(?![\d.]))?", re.IGNORECASE)
_LINE_NUMBER = re.compile(r"N\d+\s*", re.IGNORECASE)
#: The rest of a command line: words, each a letter and (for valid words) a number, spaces optional.
_WORD = re.compile(r"\s*([A-Za-z])([^A-Za-z\s]*)")

#: Commands that change nothing the tests look at. M117's text is a message, not words.
_IGNORED = {"G4", "G21", "M18", "M84", "M117", "M400"}
#: Commands whose words may be bare axis flags ("G28 X Y", "M84 E").
_FLAGS_ALLOWED = {"G28", "M18", "M84"}
_TEMPERATURES = {"M104", "M109", "M140", "M190"}


def _moved(a: float, b: float) -> bool:
    """Whether a coordinate changed; unknown to unknown counts as unchanged."""
    return not (a == b or (math.isnan(a) and math.isnan(b)))


@dataclass(frozen=True)
class Move:
    """One G0/G1 line (including those that move nothing, e.g. "G1 F1200")."""

    line: int  # 1-based line number in the text
    start: Point  # x, y, z before the move, mm (NaN where still unknown)
    end: Point
    e: float  # filament advanced by this move, mm (negative = retraction), whatever the E mode
    feed: float  # mm/min in effect (modal F, shared by G0 and G1; NaN before the first F)
    command: str  # "G0" or "G1"

    @property
    def xy_length(self) -> float:
        return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)

    def axis_speeds(self) -> dict[str, float]:
        """Each axis' speed along this move, mm/s, as Marlin plans it: the feed is the speed along
        the XYZ path (along E for a move of E alone), each axis moving its share of it."""
        deltas = dict(zip("XYZ", (b - a for a, b in zip(self.start, self.end))), E=self.e)
        xyz = math.sqrt(sum(d * d for a, d in deltas.items() if a != "E"))
        length = xyz if xyz > 0 else abs(self.e)
        if not length:
            return {a: 0.0 for a in deltas}
        return {a: self.feed / 60.0 * abs(d) / length for a, d in deltas.items()}

    @property
    def moves_xy(self) -> bool:
        return _moved(self.start[0], self.end[0]) or _moved(self.start[1], self.end[1])

    @property
    def extruding(self) -> bool:
        """A deposit: filament pushed while the nozzle moves in XY."""
        return self.e > 0 and self.moves_xy

    @property
    def kind(self) -> str:
        """"extrude", "travel" (XY motion, e <= 0), "retract"/"unretract" (E only, or with Z), "z" or "none"."""
        if self.moves_xy:
            return "extrude" if self.e > 0 else "travel"
        if self.e < 0:
            return "retract"
        if self.e > 0:
            return "unretract"
        if self.e == 0 and _moved(self.start[2], self.end[2]):
            return "z"
        return "none"


@dataclass
class Program:
    moves: list[Move] = field(default_factory=list)
    temperatures: list[tuple[int, str, float]] = field(default_factory=list)  # (line, code, S)
    fans: list[tuple[int, float]] = field(default_factory=list)  # (line, S 0-255); M107 -> 0
    pauses: list[tuple[int, str]] = field(default_factory=list)  # (line, message) of M0/M1
    comments: list[tuple[int, str]] = field(default_factory=list)  # (line, text without ';', stripped)
    homed_at: list[int] = field(default_factory=list)  # lines of G28
    e_mode: str = "absolute"  # at the end of the program: "absolute" (M82) or "relative" (M83)
    unknown: list[tuple[int, str]] = field(default_factory=list)  # (line, code) of unmodelled commands

    def header(self, key: str) -> str | None:
        """The value of the first comment "KEY:value" (value stripped), or None."""
        for _, text in self.comments:
            name, colon, value = text.partition(":")
            if colon and name.strip() == key:
                return value.strip()
        return None

    def extruding_moves(self) -> list[Move]:
        return [move for move in self.moves if move.extruding]

    def total_e(self) -> float:
        """Net filament, mm (NaN if any move's E was unknown)."""
        return math.fsum(move.e for move in self.moves)

    def segments(self, kind: str) -> np.ndarray:
        """(k, 2, 2): the XY start and end of the moves of that kind, in order."""
        rows = [(m.start[:2], m.end[:2]) for m in self.moves if m.kind == kind]
        return np.array(rows, dtype=float).reshape(-1, 2, 2)


class _Reader:
    def __init__(self) -> None:
        self.program = Program()
        self.position = [math.nan, math.nan, math.nan]
        self.e_position = math.nan
        self.xyz_relative = False  # Marlin boots absolute
        self.e_relative = False
        self.feed = math.nan

    def read_line(self, number: int, line: str) -> None:
        body, semicolon, comment = line.partition(";")
        if semicolon:
            self.program.comments.append((number, comment.strip()))
        body = _strip_checksum(body.strip(), number)
        body = body[m.end():] if (m := _LINE_NUMBER.match(body)) else body
        if not body:
            return
        match = _CODE.match(body)
        if match is None:
            raise ValueError(f"line {number}: no G, M or T command in {body!r}")
        letter, value, sub = match.groups()
        code = f"{letter.upper()}{int(value)}" + (f".{int(sub)}" if sub is not None else "")
        rest = body[match.end():]
        if code == "G20":
            raise ValueError(f"line {number}: G20 (inches) is refused: programs must be in mm")
        handler = getattr(self, "_" + code.replace(".", "_"), None)  # _G1, _M106, ...
        if code in ("M0", "M1"):
            self.program.pauses.append((number, rest.strip()))  # the rest of the line is the message
        elif code == "M117":
            pass  # a message for the display, not words
        elif code in _TEMPERATURES:
            self._temperature(number, code, _words(rest, number, code))
        elif code in _IGNORED:
            _words(rest, number, code)  # still refuse malformed words
        elif handler is not None:
            handler(number, code, _words(rest, number, code))
        else:
            self.program.unknown.append((number, code))  # its words are not read

    # -- motion ----------------------------------------------------------------------------------

    def _G0(self, number: int, code: str, words: dict[str, float | None]) -> None:
        _only(words, "XYZEF", number, code)
        if "F" in words:
            if words["F"] <= 0:
                raise ValueError(f"line {number}: feed must be positive, got F{words['F']}")
            self.feed = words["F"]
        start = tuple(self.position)
        for i, axis in enumerate("XYZ"):
            if axis in words:
                self.position[i] = self.position[i] + words[axis] if self.xyz_relative else words[axis]
        e = 0.0
        if "E" in words:
            if self.e_relative:
                e = words["E"]
                self.e_position += e
            else:
                e = words["E"] - self.e_position
                self.e_position = words["E"]
        self.program.moves.append(Move(number, start, tuple(self.position), e, self.feed, code))

    _G1 = _G0

    def _G28(self, number: int, code: str, words: dict[str, float | None]) -> None:
        axes = [axis for axis in "XYZ" if axis in words] or ["X", "Y", "Z"]
        for axis in axes:
            self.position["XYZ".index(axis)] = 0.0
        self.program.homed_at.append(number)

    def _G92(self, number: int, code: str, words: dict[str, float | None]) -> None:
        _only(words, "XYZE", number, code)
        if not words:
            words = {"X": 0.0, "Y": 0.0, "Z": 0.0, "E": 0.0}
        for i, axis in enumerate("XYZ"):
            if axis in words:
                self.position[i] = words[axis]
        if "E" in words:
            self.e_position = words["E"]

    # -- modes: G90/G91 set all four axes (clearing M82/M83), M82/M83 then set E alone -------------

    def _G90(self, number: int, code: str, words: dict[str, float | None]) -> None:
        _only(words, "", number, code)
        self.xyz_relative = self.e_relative = False
        self.program.e_mode = "absolute"

    def _G91(self, number: int, code: str, words: dict[str, float | None]) -> None:
        _only(words, "", number, code)
        self.xyz_relative = self.e_relative = True
        self.program.e_mode = "relative"

    def _M82(self, number: int, code: str, words: dict[str, float | None]) -> None:
        _only(words, "", number, code)
        self.e_relative = False
        self.program.e_mode = "absolute"

    def _M83(self, number: int, code: str, words: dict[str, float | None]) -> None:
        _only(words, "", number, code)
        self.e_relative = True
        self.program.e_mode = "relative"

    # -- temperatures and fans --------------------------------------------------------------------

    def _temperature(self, number: int, code: str, words: dict[str, float | None]) -> None:
        # M109/M190 R<t> is S<t> that also waits while cooling down.
        value = words.get("S", words.get("R") if code in ("M109", "M190") else None)
        if value is None:
            self.program.unknown.append((number, code))  # no target: nothing we model
        else:
            self.program.temperatures.append((number, code, value))

    def _M106(self, number: int, code: str, words: dict[str, float | None]) -> None:
        self.program.fans.append((number, words.get("S", 255.0)))

    def _M107(self, number: int, code: str, words: dict[str, float | None]) -> None:
        self.program.fans.append((number, 0.0))


def _strip_checksum(body: str, number: int) -> str:
    """Remove a "*<checksum>" suffix after checking it (XOR of every byte before the '*')."""
    if "*" not in body:
        return body
    checked, _, checksum = body.rpartition("*")
    if not checksum.strip().isdigit():
        raise ValueError(f"line {number}: malformed checksum {'*' + checksum!r}")
    expected = 0
    for byte in checked.encode():
        expected ^= byte
    if int(checksum) != expected:
        raise ValueError(f"line {number}: checksum {int(checksum)} does not match the line ({expected})")
    return checked.rstrip()


def _words(rest: str, number: int, code: str) -> dict[str, float | None]:
    """The words after the command, letter (upper case) -> value (None for a bare flag, where allowed)."""
    words: dict[str, float | None] = {}
    position = 0
    for match in _WORD.finditer(rest):
        if match.start() != position:
            break
        position = match.end()
        letter, text = match.group(1).upper(), match.group(2)
        if letter in words:
            raise ValueError(f"line {number}: {letter} given twice in {code}")
        if text == "" and code in _FLAGS_ALLOWED:
            words[letter] = None
        elif _NUMBER.fullmatch(text):
            words[letter] = float(text)
        else:
            raise ValueError(f"line {number}: malformed word {letter + text!r}")
    if rest[position:].strip():
        raise ValueError(f"line {number}: unexpected text {rest[position:].strip()!r}")
    return words


def _only(words: dict[str, float | None], letters: str, number: int, code: str) -> None:
    unexpected = sorted(set(words) - set(letters))
    if unexpected:
        raise ValueError(f"line {number}: {code} does not take {', '.join(unexpected)}")


def read_gcode(text: str) -> Program:
    """Read a whole program. Raises ValueError naming the line for malformed words and for G20."""
    reader = _Reader()
    for number, line in enumerate(text.split("\n"), start=1):
        reader.read_line(number, line.rstrip("\r"))
    return reader.program
