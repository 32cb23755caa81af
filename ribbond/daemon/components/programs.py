"""Programs the daemon streams, read as G-code (no printer answers): the time line of a program
(its own time estimate per command, and the ribbon each command belongs to) for progress and time
left, and the line-by-line check of a plain G-code program against the printer profile.

Commands are counted exactly as ``printer.link.prepare_program`` makes them (comments, blank lines,
``N…`` numbers and ``*…`` checksums dropped), so index i here is line i of the stream.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ribbond.gcode.checker import Checked, GcodeChecker
from ribbond.gcode.estimate import move_times
from ribbond.gcode.profiles import PrinterProfile
from ribbond.printer import codec
from ribbond.printer.link import prepare_program

__all__ = ["Part", "Timeline", "check_plain_program", "check_program", "command_of", "program_parts", "program_timeline",
           "resumed_program"]

_NUMBER = re.compile(r"^N\d+\s+")
_RIBBON = re.compile(r"^;TYPE:RIBBON\s+\d+\s+\((\d+) of (\d+)\)")
_PART = re.compile(r"^;TYPE:(\S+)\s*(\d*)")
#: Commands that wait for a heater: the program prints only after the last of them.
_HEAT_WAITS = ("M109", "M190", "M116")


def command_of(raw: str) -> str | None:
    """The command a program line streams as (None for a comment or blank line)."""
    command = codec.strip_comment(raw)
    if not command:
        return None
    command = _NUMBER.sub("", command).split("*", 1)[0].strip()
    return command or None


def _words(command: str, where: str) -> tuple[str, dict[str, float | None]]:
    parts = command.split()
    code = parts[0].upper()
    args: dict[str, float | None] = {}
    for word in parts[1:]:
        letter, value = word[0].upper(), word[1:]
        if not value:
            args[letter] = None
            continue
        try:
            args[letter] = float(value)
        except ValueError:
            if code.startswith("M117") or code.startswith("M118"):
                continue                                    # messages carry text
            raise ValueError(f"{where}: {word!r} is not a letter and a number") from None
    return code, args


@dataclass(frozen=True)
class Timeline:
    """What a program's own time estimate says about each of its commands.

    Attributes
    ----------
    at : (n,) estimated seconds from the program's start to the end of command i (heater waits
        count 0: the estimate is of motion, so heating never inflates the time left).
    ribbon : (n,) the ribbon command i belongs to, numbered from 1 (0 before the first).
    ribbons : how many ribbons the program prints (0: no ribbon comments, e.g. plain G-code).
    first : how many commands come before the printing (the heating and the preamble): the
        stream prints once that many are acknowledged.
    """

    at: np.ndarray
    ribbon: np.ndarray
    ribbons: int
    first: int

    @property
    def total(self) -> float:
        """Estimated seconds of the whole program."""
        return float(self.at[-1]) if len(self.at) else 0.0

    def done_s(self, count: int) -> float:
        """Estimated seconds of the program done once its first ``count`` commands are."""
        if count <= 0 or not len(self.at):
            return 0.0
        return float(self.at[min(count, len(self.at)) - 1])

    def ribbon_at(self, count: int) -> int:
        """The ribbon being printed once the first ``count`` commands are done."""
        if count <= 0 or not len(self.ribbon):
            return 0
        return int(self.ribbon[min(count, len(self.ribbon)) - 1])


def program_timeline(lines: Sequence[str], profile: PrinterProfile) -> Timeline:
    """The time line of a program (text lines), estimated with the profile's accelerations and
    junction deviation (``gcode.estimate.move_times``, as the program's writer estimates it)."""
    mo = profile.motion
    pos = [0.0, 0.0, 0.0]
    absolute = True
    feed = mo.travel_speed
    starts, ends, es, feeds, index = [], [], [], [], []
    ribbon_of: list[int] = []
    ribbon = ribbons = 0
    type_at: int | None = None
    last_wait = -1
    first_extrusion: int | None = None
    n = 0
    for raw in lines:
        stripped = raw.strip()
        found = _RIBBON.match(stripped)
        if found:
            ribbon, ribbons = int(found.group(1)), max(ribbons, int(found.group(2)))
        if stripped.startswith(";TYPE:") and type_at is None:
            type_at = n
        command = command_of(raw)
        if command is None:
            continue
        try:
            code, args = _words(command, f"line {n}")
        except ValueError:
            code, args = command.split()[0].upper(), {}
        if code == "G90":
            absolute = True
        elif code == "G91":
            absolute = False
        elif code == "G28":
            axes = [i for i, a in enumerate("XYZ") if a in args] or [0, 1, 2]
            for i in axes:
                pos[i] = 0.0
        elif code in _HEAT_WAITS and first_extrusion is None:
            last_wait = n
        elif code in ("G0", "G1"):
            if args.get("F"):
                feed = float(args["F"] or 0) / 60.0
            new = list(pos)
            for i, a in enumerate("XYZ"):
                if args.get(a) is not None:
                    new[i] = float(args[a]) if absolute else pos[i] + float(args[a])  # type: ignore[arg-type]
            e = float(args.get("E") or 0.0)
            if e > 0 and first_extrusion is None:
                first_extrusion = n
            starts.append(list(pos))
            ends.append(new)
            es.append(e)
            feeds.append(max(feed, 1e-3))
            index.append(n)
            pos = new
        ribbon_of.append(ribbon)
        n += 1
    per = np.zeros(n)
    if index:
        t = move_times(np.array(starts), np.array(ends), np.array(es), np.array(feeds),
                       mo.acceleration, mo.junction_deviation, mo.retract_speed)
        per[np.array(index)] = t
    first = type_at if type_at is not None else last_wait + 1
    return Timeline(at=np.cumsum(per), ribbon=np.array(ribbon_of, dtype=int), ribbons=ribbons,
                    first=min(max(first, 0), n))


def check_program(lines: Sequence[str], profile: PrinterProfile, source: str = "program") -> list[str]:
    """Check a plain G-code program line by line against the printer profile; the commands to
    stream (feed rates clamped to the profile's limits: ``check_plain_program``)."""
    return check_plain_program(lines, profile, source).commands


def check_plain_program(lines: Sequence[str], profile: PrinterProfile, source: str = "program") -> Checked:
    """Check a plain G-code program line by line against the printer profile (``checker``: the
    same check as the console's), from an unknown position in absolute mode.

    Refused, naming the line: what ``prepare_program`` refuses (M110, M112, too long, not ASCII);
    what ``checker.GcodeChecker`` refuses (outside the frame, below the fabric, a position not
    known, too hot, moves it cannot follow). Homing (G28: machine 0, as the programs ribbond writes
    assume) is allowed although home is outside the frame. Feed rates above the profile's maximum
    speeds are clamped as the firmware would (``Checked.lines``: the program with those F words).

    Raises
    ------
    ValueError
        ``"<source>, line L: <what is wrong>"``; an empty program too.
    """
    commands = prepare_program(lines, source)
    if not commands:
        raise ValueError(f"{source}: no G-code commands in the file")
    return GcodeChecker(profile, source).check(lines)


@dataclass(frozen=True)
class Part:
    """One independent piece of a program (a ribbon, a registration mark): the section from its
    ``;TYPE:`` comment to the next one (issue 16). Indices are command indices (stream lines).

    Attributes
    ----------
    ordinal : the part's place in the program, from 0.
    kind : the ``;TYPE:`` word (``RIBBON``, ``REGISTRATION``, …); number : the number after it.
    begin : its first command (the travel to it).
    first_e : its first command that feeds filament (None: it prints nothing). Sent only once the
        host has recorded that the part started.
    sync : the first ``M400`` after its last extrusion: acknowledged, it proves every move of the
        part executed (None: no proof possible; programs written before issue 16).
    """

    ordinal: int
    kind: str
    number: int | None
    begin: int
    first_e: int | None
    sync: int | None


def _feeds(command: str) -> tuple[bool, bool]:
    """Whether a G0/G1 command feeds filament, and whether it also moves in X/Y."""
    words = command.split()
    if not words or words[0].upper() not in ("G0", "G1"):
        return False, False
    e = next((w[1:] for w in words[1:] if w[:1].upper() == "E"), None)
    try:
        feeds = e is not None and float(e) > 0
    except ValueError:
        feeds = False
    return feeds, any(w[:1].upper() in "XY" for w in words[1:])


def program_parts(lines: Sequence[str]) -> list[Part]:
    """The parts of a program (text lines), in print order; none for a program without ``;TYPE:``."""
    found: list[dict[str, object]] = []
    n = 0
    for raw in lines:
        mark = _PART.match(raw.strip())
        if mark:
            found.append({"kind": mark.group(1), "number": int(mark.group(2)) if mark.group(2) else None,
                          "begin": n, "first_e": None, "last_xy_e": None, "sync": None})
        command = command_of(raw)
        if command is None:
            continue
        if found:
            part = found[-1]
            feeds, xy = _feeds(command)
            if feeds and part["first_e"] is None:
                part["first_e"] = n
            if feeds and xy:
                part["last_xy_e"], part["sync"] = n, None
            elif command.split()[0].upper() == "M400" and part["sync"] is None:
                part["sync"] = n
        n += 1
    return [Part(ordinal=i, kind=str(p["kind"]), number=p["number"], begin=int(p["begin"]),  # type: ignore[arg-type]
                 first_e=p["first_e"], sync=p["sync"]) for i, p in enumerate(found)]  # type: ignore[arg-type]


def resumed_program(lines: Sequence[str], start: int, modal: dict[str, object], profile: PrinterProfile,
                    note: str) -> list[str]:
    """The program that prints ``lines``' parts from ordinal ``start`` on (then its footer).

    The prelude restores what the skipped lines had set up: units, absolute positioning, relative
    extrusion, the heaters (``modal``: ``resume.modal_state`` at the part's first command), homing,
    the fan, a retraction (the part's own travel primes the nozzle again, as after the part before
    it), the head at the safe height over the position the part starts from, then down to it, and
    ``G92 E0``. The profile's start G-code is not repeated (a purge line would land on the fabric).

    Raises
    ------
    ValueError
        ``start`` is not a part of the program, or the position before it is unknown.
    """
    parts = program_parts(lines)
    if not 0 <= start < len(parts):
        raise ValueError(f"part {start + 1}: the program has {len(parts)} parts")
    x, y, z = (modal.get(k) for k in ("x", "y", "z"))
    if x is None or y is None or z is None:
        raise ValueError(f"part {start + 1}: the head's position before it is not known from the program")
    prof, mo, r = profile, profile.motion, profile.retraction
    nozzle = modal.get("nozzle") or prof.temperatures.nozzle
    bed = modal.get("bed") if modal.get("bed") is not None else prof.temperatures.bed
    safe = max(float(z) + r.z_hop, prof.layers.fabric_z + prof.layers.safe_height)  # type: ignore[arg-type]
    head = [f";RESUMED: {note}"] + (["G21"] if prof.gcode.emit_units else []) + ["G90", "M83"]
    if bed:
        head += [f"M140 S{bed:.0f}"]
    head += [f"M104 S{nozzle:.0f}", "G28"] + ([f"M190 S{bed:.0f}"] if bed else []) + [f"M109 S{nozzle:.0f}"]
    if modal.get("fan"):
        head.append(f"M106 S{int(modal['fan'])}")  # type: ignore[call-overload]
    if r.length > 0:
        head.append(f"G1 E{-r.length:.5f} F{mo.retract_speed * 60:.0f}")
    head += [f"G0 Z{safe:.3f} F{mo.z_speed * 60:.0f}", f"G0 X{x:.3f} Y{y:.3f} F{mo.travel_speed * 60:.0f}",
             f"G0 Z{z:.3f} F{mo.z_speed * 60:.0f}", "G92 E0"]
    # the text from the part's ;TYPE: comment on
    begin = parts[start].begin
    n, at = 0, len(lines)
    for i, raw in enumerate(lines):
        if n == begin and _PART.match(raw.strip()):
            at = i
            break
        if command_of(raw) is not None:
            n += 1
    return head + list(lines[at:])
