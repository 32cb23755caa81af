"""The one check of G-code against the printer profile (issue 22): plain G-code jobs
(``programs.check_program``) and the console (``manual.ManualControl.gcode``) both go through it,
so whatever a person types or uploads passes the same rules as ``goto``, ``jog`` and ``heat``.

Refused, naming the line or command and the limit: a move whose end is outside the frame's
printable rectangle or below the fabric; a move from a position the check does not know (home
first); a temperature above the profile's ``nozzle_max`` / ``bed_max`` (every heater command the
check knows: M104, M109, M140, M190 with S, R or B, M303 by its heater) or below 0; arcs and other
moves it cannot follow (G2/G3, probing, parking, babysteps), inches, G92 on X/Y/Z, and the settings
that would defeat the limits (steps per mm, maximum feed rates, home offsets, software endstops, a
feed override (M220) or a flow (M221) outside the profile's ``[adjust]`` ranges).

Beside a running program (``printing=True``: the console while a job prints, issue 36) only the
adjustments go in: M220 and M221 within those ranges, M104 between ``adjust.nozzle_min`` and
``nozzle_max``, M140 up to ``bed_max``, and the queries M105 and M114; a move, a wait (M109, M190,
M400) or anything else is refused naming it.

Feed rates above the profile's maximum speeds are not refused but clamped where the firmware
would clamp them: Marlin scales a move's speed so that no axis exceeds its maximum feed rate
(X and Y ``max_xy_speed``, Z ``max_z_speed``, E ``max_e_speed``), so ``G1 Z15 F6000`` runs at
``max_z_speed``. The checked commands carry the clamped F word (and the asked-for feed is given
again on the next move that relies on it), and the result says how many moves were clamped.

``check_stitch_marks`` checks a design's front program against ``design.stitch_marks`` (issue 26):
it follows the program as the check does and finds each stroke of each mark printed over its length.

The modal state is followed as Marlin keeps it: G90/G91 (which set E's mode too), M82/M83,
G92 E, the feed (shared by G0 and G1), G28 (the axes homed to machine 0, as the programs ribbond
writes assume), M18/M84 (motors off: the position is lost).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ribbond.design.format import StitchMark
from ribbond.printer import codec
from .profiles import PrinterProfile

__all__ = ["Checked", "GcodeChecker", "Modal", "NotWhilePrinting", "check_stitch_marks", "extruded_segments",
           "parse_command", "uncovered"]

_NUMBER_PREFIX = re.compile(r"^N\d+\s*", re.IGNORECASE)
_CODE = re.compile(r"^([GMT])0*(\d+)(\.\d+)?", re.IGNORECASE)
_WORD = re.compile(r"\s*([A-Za-z])([^A-Za-z\s]*)")
#: Commands whose rest is text (a message, a file name), never parsed as words.
_TEXT = frozenset({"M0", "M1", "M23", "M28", "M30", "M117", "M118", "M862", "M928"})
#: G-codes the check follows; every other G-code may move the head in ways it cannot follow.
_G_FOLLOWED = frozenset({"G0", "G1", "G4", "G10", "G11", "G21", "G28", "G90", "G91", "G92"})
#: M-codes refused, and why: each would take the head or the limits out of the check's hands.
_M_REFUSED = {
    "M24": "starts a print from the SD card, which is not checked",
    "M32": "starts a print from the SD card, which is not checked",
    "M33": "starts a print from the SD card, which is not checked",
    "M48": "probes the bed (the nozzle would go down into the fabric)",
    "M92": "changes steps per mm: positions would no longer be the checked millimetres",
    "M125": "parks the head where the check cannot follow",
    "M141": "sets a chamber temperature, which the profile has no limit for",
    "M191": "sets a chamber temperature, which the profile has no limit for",
    "M203": "raises the firmware's maximum feed rates above the checked ones",
    "M206": "moves the coordinate system (home offset): positions would no longer be the checked ones",
    "M211": "switches the software endstops",
    "M290": "babysteps the nozzle (it could go down into the fabric)",
    "M428": "moves the coordinate system (home offset): positions would no longer be the checked ones",
    "M600": "parks the head for a filament change where the check cannot follow",
    "M665": "changes the machine's geometry",
    "M666": "changes the machine's geometry",
}
#: Heater commands: the profile limit each one's temperature words are checked against.
_NOZZLE, _BED = ("nozzle", "nozzle_max"), ("bed", "bed_max")
_HEATERS = {"M104": _NOZZLE, "M109": _NOZZLE, "M140": _BED, "M190": _BED}
_EPS = 1e-6
#: The percentages a person may change: the code -> (what it sets, its range in ``profile.adjust``).
_ADJUSTED = {"M220": ("feed override", "speed_percent"), "M221": ("flow", "flow_percent")}
#: What may go in beside a running program, and the words each may carry (issue 36).
_WHILE_PRINTING: dict[str, frozenset[str]] = {
    "M220": frozenset("S"), "M221": frozenset("ST"), "M104": frozenset("ST"), "M140": frozenset("S"),
    "M105": frozenset(), "M114": frozenset(),
}


class NotWhilePrinting(ValueError):
    """A command refused only because a program is printing (a move, a wait, a nozzle target below
    ``adjust.nozzle_min``): allowed once the job is paused or done. Values beyond the profile's
    limits raise a plain ``ValueError``."""


def parse_command(command: str, where: str) -> tuple[str, dict[str, float | None]]:
    """A command's code (``G1``; ``G01`` is ``G1``, spaces between words optional, as Marlin reads
    them) and its words (letter -> number, None for a bare flag such as ``G28 X``).

    Raises
    ------
    ValueError
        ``"<where>: …"``: not a G/M/T command, or a word that is not a letter and a number.
    """
    text = _NUMBER_PREFIX.sub("", command.strip()).split("*", 1)[0].strip()
    found = _CODE.match(text)
    if not found:
        raise ValueError(f"{where}: {text.split()[0] if text else text!r} is not a G-code command (G…, M… or T…)")
    code = f"{found.group(1).upper()}{int(found.group(2))}{found.group(3) or ''}"
    args: dict[str, float | None] = {}
    if code.split(".")[0] in _TEXT:
        return code, args
    rest = text[found.end():]
    for letter, value in _WORD.findall(rest):
        try:
            number = float(value) if value else None
        except ValueError:
            raise ValueError(f"{where}: {letter + value!r} is not a letter and a number") from None
        if number is not None and not math.isfinite(number):
            raise ValueError(f"{where}: {letter + value!r} is not a finite number")
        args[letter.upper()] = number
    if _WORD.sub("", rest).strip():
        raise ValueError(f"{where}: {rest.strip()!r} is not a list of words (a letter and a number each)")
    return code, args


@dataclass
class Modal:
    """What the printer holds when the next command runs, as far as the check can tell.

    Attributes
    ----------
    pos : X, Y, Z (mm, the program's coordinates), None where not known.
    e : the E position (mm), None where not known (only absolute E needs it).
    absolute, e_absolute : G90/G91 (X, Y, Z), M82/M83 (E).
    feed : the feed asked for (the last F word, mm/min); None: not known (the firmware's own).
    sent_feed : the feed the checked commands set (after clamping), mm/min.
    homed : a G28 was checked; motors_off : an M18/M84 switched motors off.
    """

    pos: list[float | None] = field(default_factory=lambda: [None, None, None])
    e: float | None = None
    absolute: bool = True
    e_absolute: bool = True
    feed: float | None = None
    sent_feed: float | None = None
    homed: bool = False
    motors_off: bool = False

    def known(self) -> tuple[float, float, float] | None:
        """The head's position if every axis is known."""
        x, y, z = self.pos
        return None if x is None or y is None or z is None else (x, y, z)


@dataclass(frozen=True)
class Checked:
    """A checked program or batch: the commands to send (feed rates clamped), the same text lines
    with the clamped F words (comments kept), what was clamped, and the modal state after it."""

    commands: list[str]
    lines: list[str]
    clamped: dict[str, int]          # the limiting axis ("X", "Y", "Z", "E") -> moves clamped by it
    first_clamped: int | None        # the first clamped line (or command) number
    modal: Modal

    def notes(self, profile: PrinterProfile, unit: str = "line") -> list[str]:
        """What was changed, as a person reads it: e.g. "37 moves' feed rates clamped to the
        profile (Z ≤ 40 mm/s), as the firmware limits feed rates; the first at line 12"."""
        if not self.clamped:
            return []
        limits = _limits(profile)
        by = ", ".join(f"{axis} ≤ {limits[axis]:g} mm/s" for axis in sorted(self.clamped))
        n = sum(self.clamped.values())
        moves = f"{n} moves' feed rates" if n != 1 else "1 move's feed rate"
        return [f"{moves} clamped to the profile ({by}), as the firmware limits feed rates; "
                f"the first at {unit} {self.first_clamped}"]


def _limits(profile: PrinterProfile) -> dict[str, float]:
    mo = profile.motion
    return {"X": mo.max_xy_speed, "Y": mo.max_xy_speed, "Z": mo.max_z_speed, "E": mo.max_e_speed}


def _feed_text(feed: float) -> str:
    """An F value never above ``feed`` (rounded down to 0.1 mm/min)."""
    return f"{math.floor(feed * 10 + 1e-6) / 10:.1f}".rstrip("0").rstrip(".")


def _with_feed(command: str, feed: str) -> str:
    """``command`` (a G0/G1 without N or checksum) with its F word set to ``feed``."""
    words = re.findall(r"[A-Za-z][^A-Za-z\s]*", command)
    kept = [w for w in words[1:] if w[0].upper() != "F"]
    return " ".join([words[0], *kept, f"F{feed}"])


class GcodeChecker:
    """Checks commands one at a time against ``profile``, carrying the modal state (``modal``).

    ``where(number, command)`` names a line in refusals (default ``"<source>, line N"``).
    ``printing``: the commands go in beside a running program (the console while a job prints):
    only its adjustments (M220, M221, M104, M140 within ``profile.adjust``) and M105 / M114."""

    def __init__(self, profile: PrinterProfile, source: str = "program", modal: Modal | None = None,
                 where: Callable[[int, str], str] | None = None, printing: bool = False) -> None:
        self.profile = profile
        self.printing = printing
        self.modal = modal if modal is not None else Modal()
        self.where = where or (lambda number, _command: f"{source}, line {number}")
        self.limits = _limits(profile)
        self.clamped: Counter[str] = Counter()
        self.first_clamped: int | None = None

    def check(self, lines: Sequence[str]) -> Checked:
        """Check every line; the commands (clamped) and the lines with the clamped F words."""
        commands, out = [], []
        for number, raw in enumerate(lines, start=1):
            command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("*", 1)[0].strip()
            if not command:
                out.append(raw)
                continue
            checked = self.command(number, command)
            commands.append(checked)
            out.append(raw if checked == command else checked + _comment_of(raw))
        return Checked(commands, out, dict(self.clamped), self.first_clamped, replace(self.modal))

    def command(self, number: int, command: str) -> str:
        """Check one command (no comment, no N, no checksum); the command to send (its F word
        clamped), the modal state advanced. Raises ``ValueError`` naming ``where`` and the limit."""
        where = self.where(number, command)
        code, args = parse_command(command, where)
        if self.printing:
            self._while_printing(code, args, where)
        self._refuse_unfollowed(code, args, where)
        if code in _HEATERS or code == "M303":
            self._temperatures(code, args, where)
        elif code in ("G0", "G1"):
            return self._move(number, command, args, where)
        else:
            self._modes(code, args)
        return command

    # ------------------------------------------------------------------ what is never sent

    def _refuse_unfollowed(self, code: str, args: dict[str, float | None], where: str) -> None:
        if code in ("G2", "G3"):
            raise ValueError(f"{where}: {code} arcs are not checked against the frame; convert them to G1 moves")
        if code == "G20":
            raise ValueError(f"{where}: G20 (inches) is not supported; the profile's limits are in mm")
        if code == "G92" and (any(a in args for a in "XYZ") or not args):
            raise ValueError(f"{where}: G92 redefines the X/Y/Z position, which the frame check cannot "
                             "follow (G92 E… is fine)")
        if code.startswith("G") and code not in _G_FOLLOWED:
            raise ValueError(f"{where}: {code} is not a command the check follows (it may move the head "
                             "where the frame and fabric check cannot see); send G0/G1 moves instead")
        base = code.split(".")[0]
        if base in _M_REFUSED:
            raise ValueError(f"{where}: {base} {_M_REFUSED[base]}; not allowed on the fabric")
        if base in _ADJUSTED and args.get("S") is not None:
            self._percent(base, args["S"], where)  # type: ignore[arg-type]

    def _percent(self, code: str, value: float, where: str) -> None:
        """M220 S / M221 S within the profile's ``adjust`` range."""
        what, name = _ADJUSTED[code]
        low, high = getattr(self.profile.adjust, name)
        if value > high + _EPS:
            raise ValueError(f"{where}: {code} S{value:g} sets the {what} above {high:g} % (the profile's "
                             f"adjust.{name} is {low:g}-{high:g} %)"
                             + (", so moves would run faster than the profile's limits allow" if code == "M220" else ""))
        if value < low - _EPS:
            raise ValueError(f"{where}: {code} S{value:g} sets the {what} below {low:g} % (the profile's "
                             f"adjust.{name} is {low:g}-{high:g} %)")

    def _while_printing(self, code: str, args: dict[str, float | None], where: str) -> None:
        """While a program prints only its adjustments and the queries go in beside it (issue 36):
        nothing that moves the head, waits or changes what the program's lines mean."""
        if code not in _WHILE_PRINTING:
            moves = " (it moves the head)" if code in ("G0", "G1", "G28") else ""
            raise NotWhilePrinting(f"{where}: {code}{moves} is not accepted while a program prints; only "
                             f"{', '.join(sorted(_WHILE_PRINTING))} are (pause the job first for anything else)")
        extra = sorted(set(args) - _WHILE_PRINTING[code])
        if extra:
            raise NotWhilePrinting(f"{where}: {code} {extra[0]}… is not accepted while a program prints "
                             f"(only {', '.join(sorted(_WHILE_PRINTING[code])) or 'the bare command'})")
        if code in ("M220", "M221") and args.get("S", 0) is None:
            raise ValueError(f"{where}: {code} S needs a number (a percentage)")
        nozzle = args.get("S")
        low = self.profile.adjust.nozzle_min
        if code == "M104" and nozzle is not None and nozzle < low - _EPS:
            raise NotWhilePrinting(f"{where}: nozzle {nozzle:g} °C while printing is below the profile's "
                             f"adjust.nozzle_min ({low:g} °C): the nozzle would stop extruding and the "
                             "rest of the program run dry (cancel or pause the job to cool it)")

    def _temperatures(self, code: str, args: dict[str, float | None], where: str) -> None:
        temps = self.profile.temperatures
        heater, limit_name = _HEATERS.get(code) or _pid_heater(args, where)
        limit = getattr(temps, limit_name)
        for letter in ("S", "R", "B"):
            value = args.get(letter)
            if value is None:
                continue
            if value > limit + _EPS:
                raise ValueError(f"{where}: {heater} {value:g} °C is above the profile's {limit_name} "
                                 f"({limit:g} °C)")
            if value < 0:
                raise ValueError(f"{where}: {heater} {value:g} °C: a temperature must be 0 °C (off) or more")
        if args.get("I") is not None and code in _HEATERS:
            raise ValueError(f"{where}: {code} I… sets a material preset the check cannot see; give S…")

    # ------------------------------------------------------------------ the modal state

    def _modes(self, code: str, args: dict[str, float | None]) -> None:
        m = self.modal
        if code in ("G90", "G91"):
            m.absolute = m.e_absolute = code == "G90"
        elif code in ("M82", "M83"):
            m.e_absolute = code == "M82"
        elif code == "G92" and args.get("E") is not None:
            m.e = args["E"]
        elif code == "G28":
            for i in [i for i, a in enumerate("XYZ") if a in args] or [0, 1, 2]:
                m.pos[i] = 0.0
            m.homed = True
        elif code in ("M18", "M84") and "S" not in args:
            for i in [i for i, a in enumerate("XYZ") if a in args] or ([0, 1, 2] if "E" not in args else []):
                m.pos[i] = None
            m.motors_off = True

    # ------------------------------------------------------------------ moves

    def _move(self, number: int, command: str, args: dict[str, float | None], where: str) -> str:
        """A G0/G1: its end inside the frame and above the fabric, its feed clamped."""
        m = self.modal
        f = args.get("F")
        if f is not None and f <= 0:
            raise ValueError(f"{where}: feed F{f:g}: a feed rate must be above 0 mm/min")
        for letter, value in args.items():
            if letter not in "XYZEF" or value is None:
                raise ValueError(f"{where}: {letter!r} is not a letter and a number a move takes "
                                 "(X, Y, Z, E and F, each with its number)")
        start = list(m.pos)
        end = self._end(args, where)
        de = self._e_delta(args)
        if any(a in args for a in "XYZ"):
            self._inside(args, end, where)
        m.pos = end
        if f is not None:
            m.feed = f
        return self._clamped(number, command, start, end, de, f is not None)

    def _end(self, args: dict[str, float | None], where: str) -> list[float | None]:
        m = self.modal
        end = list(m.pos)
        for i, a in enumerate("XYZ"):
            value = args.get(a)
            if value is None:
                continue
            if m.absolute:
                end[i] = value
            elif end[i] is None:
                raise ValueError(f"{where}: a relative {a} move before the {a} position is known; "
                                 "home (G28) or move to an absolute position first")
            else:
                end[i] = end[i] + value  # type: ignore[operator]
        if any(a in args for a in "XYZ") and any(v is None for v in end):
            unknown = ", ".join(a for a, v in zip("XYZ", end) if v is None)
            raise ValueError(f"{where}: the head's {unknown} position is not known, so where this move "
                             "goes cannot be checked; home first (G28, or ribbonctl home) or give X, Y and Z")
        return end

    def _e_delta(self, args: dict[str, float | None]) -> float | None:
        m = self.modal
        e = args.get("E")
        if e is None:
            return 0.0
        if not m.e_absolute:
            return e
        delta = None if m.e is None else e - m.e
        m.e = e
        return delta

    def _inside(self, args: dict[str, float | None], end: list[float | None], where: str) -> None:
        x0, y0, x1, y1 = self.profile.frame.bounds
        fabric = self.profile.layers.fabric_z
        x, y, z = end
        outside_x = "X" in args and not x0 - _EPS <= x <= x1 + _EPS  # type: ignore[operator]
        outside_y = "Y" in args and not y0 - _EPS <= y <= y1 + _EPS  # type: ignore[operator]
        if outside_x or outside_y:
            raise ValueError(f"{where}: the move ends at x {x:g}, y {y:g}, outside the frame "
                             f"(x {x0:g} to {x1:g}, y {y0:g} to {y1:g} mm)")
        if z < fabric - _EPS:  # type: ignore[operator]
            raise ValueError(f"{where}: the move goes down to z {z:g}, below the fabric (z {fabric:g} mm)")

    def _clamped(self, number: int, command: str, start: list[float | None], end: list[float | None],
                 de: float | None, has_f: bool) -> str:
        """The command with the feed the firmware would run it at (Marlin's per-axis limits); after a
        clamped move, the next one that relies on the feed asked for is given it again."""
        m = self.modal
        if m.feed is None:
            return command                      # the firmware's own feed, limited by the firmware
        allowed, axis = self._allowed(start, end, de)
        if allowed < m.feed - _EPS:
            self.clamped[axis] += 1
            self.first_clamped = number if self.first_clamped is None else self.first_clamped
            text = _feed_text(allowed)
            m.sent_feed = float(text)
            return _with_feed(command, text)
        in_force = m.sent_feed is not None and abs(m.sent_feed - m.feed) < _EPS
        m.sent_feed = m.feed
        if has_f or in_force:
            return command
        return _with_feed(command, f"{m.feed:.3f}".rstrip("0").rstrip("."))

    def _allowed(self, start: list[float | None], end: list[float | None],
                 de: float | None) -> tuple[float, str]:
        """The highest feed (mm/min) at which no axis of this move exceeds its maximum speed, and
        the axis that limits it. Marlin's nominal speed is along the XYZ path (along E for an
        E-only move); where a component is not known, the named axes' own limits."""
        deltas = {a: (e - s) if s is not None and e is not None else None
                  for a, s, e in zip("XYZ", start, end)}
        deltas["E"] = de
        moving = {a: d for a, d in deltas.items() if d is None or abs(d) > _EPS}
        if not moving:
            return math.inf, ""
        if any(d is None for d in moving.values()):
            axis = min(moving, key=lambda a: self.limits[a])
            return self.limits[axis] * 60.0, axis
        xyz = math.sqrt(sum(d * d for a, d in moving.items() if a != "E"))  # type: ignore[operator]
        length = xyz if xyz > _EPS else abs(moving["E"])  # type: ignore[arg-type]
        speeds = {a: self.limits[a] * length / abs(d) for a, d in moving.items()}  # type: ignore[arg-type]
        axis = min(speeds, key=lambda a: speeds[a])
        return speeds[axis] * 60.0, axis


def _pid_heater(args: dict[str, float | None], where: str) -> tuple[str, str]:
    """M303 (PID autotune) heats heater E (-1: the bed) to S."""
    index = args.get("E")
    if index is None or index >= 0:
        return _NOZZLE
    if index == -1:
        return _BED
    raise ValueError(f"{where}: M303 E{index:g} tunes a heater the profile has no limit for")


def _comment_of(raw: str) -> str:
    """A line's ``;`` comment, kept on a rewritten line."""
    at = raw.find(";")
    return "  " + raw[at:].rstrip("\r\n") if at >= 0 else ""


# ---------------------------------------------------------------------------------------------
# a design's marks in its program (issue 26)


def extruded_segments(lines: Sequence[str], profile: PrinterProfile, source: str = "program") -> np.ndarray:
    """The XY segments a program prints along: (s, 2, 2) start and end of every move that moves in XY
    and feeds filament, followed as ``GcodeChecker`` follows the modal state (so the program is
    checked too: a refusal raises ``ValueError`` naming the line)."""
    checker = GcodeChecker(profile, source)
    m = checker.modal
    out = []
    for number, raw in enumerate(lines, start=1):
        command = _NUMBER_PREFIX.sub("", codec.strip_comment(raw)).split("*", 1)[0].strip()
        if not command:
            continue
        start, e0, e_absolute = list(m.pos), m.e, m.e_absolute
        checker.command(number, command)
        if command[:1] not in "Gg":
            continue
        code, args = parse_command(command, checker.where(number, command))
        e = args.get("E")
        if code not in ("G0", "G1") or e is None or None in start[:2] or None in m.pos[:2]:
            continue
        fed = (e - e0 if e0 is not None else 0.0) if e_absolute else e
        if fed > _EPS and (start[0], start[1]) != (m.pos[0], m.pos[1]):
            out.append(((start[0], start[1]), (m.pos[0], m.pos[1])))
    return np.asarray(out, dtype=float).reshape(-1, 2, 2)


def _samples(stroke: np.ndarray, step: float) -> np.ndarray:
    """Points along a polyline (k, 2) no farther apart than ``step``, its vertices included."""
    a, b = stroke[:-1], stroke[1:]
    counts = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / step)).astype(int)
    t = np.concatenate([np.arange(c) / c for c in counts])
    seg = np.repeat(np.arange(len(a)), counts)
    return np.vstack([a[seg] + t[:, None] * (b[seg] - a[seg]), stroke[-1:]])


def uncovered(stroke: np.ndarray, segments: np.ndarray, reach: float) -> np.ndarray:
    """The points along ``stroke`` (k, 2), sampled every ``reach``, farther than ``reach`` from every
    segment of ``segments`` (s, 2, 2): (u, 2), empty when the stroke is printed over its whole length."""
    pts = _samples(np.asarray(stroke, dtype=float), reach)
    lo, hi = pts.min(axis=0) - reach, pts.max(axis=0) + reach
    near = segments[(segments.max(axis=1) >= lo).all(axis=1) & (segments.min(axis=1) <= hi).all(axis=1)]
    if not len(near):
        return pts
    a, d = near[:, 0], near[:, 1] - near[:, 0]                                # (s, 2)
    rel = pts[:, None, :] - a[None]                                            # (n, s, 2)
    t = np.clip((rel * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-18), 0.0, 1.0)
    dist = np.linalg.norm(rel - t[..., None] * d, axis=-1).min(axis=1)
    return pts[dist > reach]


def check_stitch_marks(lines: Sequence[str], marks: Sequence[StitchMark], profile: PrinterProfile,
                       source: str = "front.gcode") -> None:
    """Check that a front program prints every stroke of a design's stitch marks (``design.stitch_marks``):
    each point along each stroke within half the nozzle's width of a printing move.

    Raises
    ------
    ValueError
        naming the program, the mark's label and stroke, and the first point left unprinted.
    """
    segments = extruded_segments(lines, profile, source)
    reach = 0.5 * profile.extruder.nozzle_diameter
    for mark in marks:
        for k, stroke in enumerate(mark.arrays()):
            missing = uncovered(stroke, segments, reach)
            if len(missing):
                x, y = missing[0]
                raise ValueError(f"{source} does not print stroke {k} of stitch mark {mark.label} "
                                 f"({'the tick' if k == 0 else 'its label'}): nothing printed within "
                                 f"{reach:g} mm of ({x:.3f}, {y:.3f})")
