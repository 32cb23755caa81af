"""The Marlin serial protocol as pure functions: encode host lines, parse printer answers.

Nothing here does I/O or keeps state. Encoding adds the line number and XOR checksum Marlin checks
(``N<n> <command>*<checksum>``); parsing turns each line the printer sends into one typed event.
The parser knows the answers of Marlin 1.x/2.x, Prusa firmware, RepRapFirmware, Smoothieware and
Repetier (their tables, with sources, are in ``tests/test_codec_dialects.py``): ``ok`` with or
without ``N``/``P``/``B`` fields, a line number (Repetier: ``ok 12``) or a temperature report after
it, ``Resend: 12``, ``Resend:12``, ``rs N12`` and ``rs 12``, Repetier's ``skip 12`` and ``wait``,
``echo:``-prefixed or bare ``busy:`` lines, leading spaces, and error lines whose text says whether
the printer has halted (``Error:``, Smoothieware's ``!!`` and ``HALT`` lines, Repetier's ``fatal:``,
RepRapFirmware's emergency stop). ``M114``'s position may come on its own line before the ``ok``
(Marlin, Klipper, RepRapFirmware) or on the ``ok`` line itself (Smoothieware: ``ok C: X:10.0000
Y:20.0000 Z:0.0000``); both parse to the same :class:`Position`. The parser keeps no state and knows
no dialect: a line means the same whoever prints it; what differs in the protocol around the lines
(when an ``ok`` comes, what follows a resend request) is ``capabilities.Dialect``'s.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

#: Marlin's MAX_CMD_SIZE is 96 bytes including the terminating NUL, so an encoded line (without its
#: newline) must stay at 95 characters or fewer.
MAX_LINE_LENGTH = 95


def checksum(text: str) -> int:
    """XOR of every byte of ``text``: the checksum Marlin compares with the number after ``*``."""
    value = 0
    for byte in text.encode("ascii"):
        value ^= byte
    return value


_COMMENT = re.compile(r"\([^)]*\)|;.*$")


def strip_comment(line: str) -> str:
    """The command part of a G-code line: ``;`` and ``( … )`` comments and outer spaces removed."""
    return _COMMENT.sub("", line).strip()


def encode(line_number: int, command: str) -> bytes:
    """Encode ``command`` as a numbered, checksummed line ready for the wire.

    Raises
    ------
    ValueError
        When the command is empty, not ASCII, contains a line break or ``*``, or when the encoded
        line would exceed :data:`MAX_LINE_LENGTH` characters (the firmware would truncate it).
    """
    command = command.strip()
    if not command:
        raise ValueError("cannot encode an empty command")
    if any(c in command for c in "\r\n*") or not command.isascii():
        raise ValueError(f"command {command!r} contains a line break, '*' or non-ASCII text")
    body = f"N{line_number} {command}"
    text = f"{body}*{checksum(body)}"
    if len(text) > MAX_LINE_LENGTH:
        raise ValueError(
            f"command {command!r} encodes to {len(text)} characters; the firmware's limit is "
            f"{MAX_LINE_LENGTH}"
        )
    return (text + "\n").encode("ascii")


#: Line numbers the link can reach in one session; a command must fit with the widest of them.
_WIDEST_LINE_NUMBER = 9_999_999


def check_sendable(command: str) -> None:
    """Raise ValueError (saying why) unless ``command`` can be sent as a numbered line."""
    encode(_WIDEST_LINE_NUMBER, command)


def encode_unnumbered(command: str) -> bytes:
    """Encode a command without line number or checksum (emergency commands such as ``M112``)."""
    command = command.strip()
    if not command or any(c in command for c in "\r\n") or not command.isascii():
        raise ValueError(f"cannot encode {command!r} as an unnumbered line")
    return (command + "\n").encode("ascii")


# --------------------------------------------------------------------------------------------
# Events: one per line received from the printer.


@dataclass(frozen=True)
class HeaterReading:
    """One heater in a temperature report: ``T:210.0 /210.0`` and its power ``@:64``."""

    name: str  # "T", "T0", "T1", "B", "C" (chamber), …
    current: float
    target: float | None
    power: int | None = None


@dataclass(frozen=True)
class Temperatures:
    """A temperature report, from ``ok T:…``, an autoreport line or a heating wait."""

    heaters: tuple[HeaterReading, ...]

    def get(self, name: str) -> HeaterReading | None:
        for heater in self.heaters:
            if heater.name == name:
                return heater
        return None

    @property
    def hotend(self) -> HeaterReading | None:
        return self.get("T") or self.get("T0")

    @property
    def bed(self) -> HeaterReading | None:
        return self.get("B")


@dataclass(frozen=True)
class Position:
    """The answer to ``M114``: ``X:0.00 Y:0.00 Z:0.00 E:0.00 Count …``, on its own line or on the
    ``ok`` line. ``e`` is None when the firmware reports no extruder (Smoothieware's robot prints
    only X, Y and Z)."""

    x: float
    y: float
    z: float
    e: float | None = None


@dataclass(frozen=True)
class Ok:
    """An acknowledgement. ``line`` is the ``N`` field of ADVANCED_OK (the acknowledged line).

    ``planner_free`` and ``queue_free`` are the ``P`` and ``B`` fields; ``temperatures`` is set for
    the ``ok T:…`` answer to ``M105``, ``position`` for the ``ok C: X:… Y:… Z:…`` answer to ``M114``
    (Smoothieware); ``text`` is whatever followed ``ok``.
    """

    line: int | None = None
    planner_free: int | None = None
    queue_free: int | None = None
    temperatures: Temperatures | None = None
    text: str = ""
    position: Position | None = None

    @property
    def advanced(self) -> bool:
        """True for an ADVANCED_OK acknowledgement (it carries the free planner and queue slots)."""
        return self.planner_free is not None and self.queue_free is not None


@dataclass(frozen=True)
class Resend:
    """The printer asks for every line from ``line`` on again."""

    line: int


class ErrorKind:
    """What an ``Error:`` line says. Plain strings on purpose: they are only ever compared."""

    CHECKSUM = "checksum"
    LINE_NUMBER = "line_number"
    NO_CHECKSUM = "no_checksum"
    NO_LINE_NUMBER = "no_line_number"
    HALTED = "halted"
    THERMAL = "thermal"
    STOPPED = "stopped"
    OTHER = "other"


@dataclass(frozen=True)
class Error:
    """An ``Error:``/``!!`` line. ``fatal`` is True when the printer has halted or stopped."""

    message: str
    kind: str
    last_line: int | None = None
    fatal: bool = False


@dataclass(frozen=True)
class Busy:
    """``busy: processing``, ``busy: paused for user``, …: the printer is alive and working."""

    reason: str


@dataclass(frozen=True)
class TemperatureReport:
    """A temperature line on its own (autoreport, heating wait)."""

    temperatures: Temperatures
    waiting: bool = False  # heating waits end their lines with ``W:<seconds>`` or ``W:?``


@dataclass(frozen=True)
class Skip:
    """Repetier's ``skip 12``: line 12 was ignored (a line it already has, or one sent after a line
    it asked for again); an ``ok`` that acknowledges nothing follows."""

    line: int


@dataclass(frozen=True)
class Wait:
    """``wait``: the printer has had nothing to do for a second, its command buffer is empty
    (Repetier's WAITING_IDENTIFIER; Marlin's NO_TIMEOUTS prints it too)."""


@dataclass(frozen=True)
class Start:
    """``start``: the firmware has (re)booted. During a job this means all its state is lost."""


@dataclass(frozen=True)
class FirmwareInfo:
    """The ``FIRMWARE_NAME:…`` line of ``M115``, split into its ``KEY:value`` fields."""

    fields: dict[str, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.fields.get("FIRMWARE_NAME", "")


@dataclass(frozen=True)
class Capability:
    """A ``Cap:NAME:1`` line of ``M115``."""

    name: str
    enabled: bool


@dataclass(frozen=True)
class UnknownCommand:
    """``echo:Unknown command: "X"``: the printer skipped a command it does not know."""

    command: str


@dataclass(frozen=True)
class Action:
    """A host action command, ``//action:pause`` and the like."""

    action: str


@dataclass(frozen=True)
class Factor:
    """A feed override or flow report: Marlin's ``FR:100%`` (M220 without words, M220.cpp) and
    ``echo:E0 Flow: 100%`` (M221 without S, M221.cpp). ``kind``: "speed" or "flow"."""

    kind: str
    percent: float


@dataclass(frozen=True)
class Echo:
    """Any other ``echo:`` line: informational."""

    text: str


@dataclass(frozen=True)
class Other:
    """A line the parser has no better name for; kept so that nothing is silently dropped."""

    text: str


Event = (
    Ok
    | Resend
    | Skip
    | Wait
    | Error
    | Busy
    | TemperatureReport
    | Position
    | Start
    | FirmwareInfo
    | Capability
    | UnknownCommand
    | Action
    | Factor
    | Echo
    | Other
)

_NUMBER = r"-?\d+(?:\.\d+)?"
# T:210.0 /210.0, T0:20.1 /0.0, B:60 /60, @:64, B@:0, W:?; Klipper writes "B:60.0 /60.0" too.
_HEATER = re.compile(rf"(?<![\w@])([TBC]\d?):\s*({_NUMBER})(?:\s*/\s*({_NUMBER}))?")
_POWER = re.compile(rf"(?<!\w)([TBC]?\d?)@:\s*({_NUMBER})")
# Smoothieware prints each heater's power right after it, "@" without a colon: "T:21.0 /0.0 @0"
_SMOOTHIE_POWER = re.compile(rf"(?<![\w@])([TBC]\d?):\s*{_NUMBER}\s*/\s*{_NUMBER}\s+@(\d+)")
_RESEND = re.compile(r"^(?:resend|rs)\s*:?\s*N?\s*(\d+)", re.IGNORECASE)
_SPEED_FACTOR = re.compile(r"^FR:\s*(\d+(?:\.\d+)?)\s*%$")
_FLOW_FACTOR = re.compile(r"^E\d+\s+Flow:\s*(\d+(?:\.\d+)?)\s*%$")
_SKIP = re.compile(r"^skip\s+(\d+)\s*$", re.IGNORECASE)
# Repetier's line check: "Error:expected line 12 got 14" (line 11 was the last it took)
_EXPECTED_LINE = re.compile(r"expected line\s+(-?\d+)", re.IGNORECASE)
# Lines that say the printer is halted without an "Error:" prefix: Smoothieware (GcodeDispatch.cpp,
# SerialConsole.cpp, TemperatureControl.cpp) and RepRapFirmware's emergency stop (GCodes.cpp).
_HALT_LINE = re.compile(r"HALT asserted|Entering Alarm/Halt state|^HALTED\b|exit HALT state"
                        r"|^Emergency Stop! Reset the controller", re.IGNORECASE)
_OK_FIELD = re.compile(r"\b([NPB])(-?\d+)\b")
_BARE_NUMBER = re.compile(r"^\s*(\d+)\s*$")
_LAST_LINE = re.compile(r"Last Line:\s*(-?\d+)", re.IGNORECASE)
_POSITION = re.compile(
    rf"^X:\s*({_NUMBER})\s+Y:\s*({_NUMBER})\s+Z:\s*({_NUMBER})\s+E\d?:\s*({_NUMBER})"
)
# Smoothieware's M114 after "ok": "C: X:10.0000 Y:20.0000 Z:0.0000", an extruder's " E:…" after it.
_OK_POSITION = re.compile(
    rf"^C:\s*X:\s*({_NUMBER})\s+Y:\s*({_NUMBER})\s+Z:\s*({_NUMBER})(?:\s+E\d?:\s*({_NUMBER}))?"
)
# M115's keys: upper case, "_" and "-" (Smoothieware's "X-SOURCE_CODE_URL"), at the start or after a
# space or a comma (Smoothieware separates its fields with ", "; RepRapFirmware writes "KEY: value").
_FIRMWARE_FIELD = re.compile(r"(?:^|(?<=[\s,]))([A-Z][A-Z0-9_-]*[A-Z0-9_]):")


def parse_temperatures(text: str) -> Temperatures | None:
    """The heaters reported in ``text``, or None when it holds no temperature report."""
    readings = {}
    for name, current, target in _HEATER.findall(text):
        if name not in readings:
            readings[name] = [float(current), float(target) if target else None, None]
    if not readings:
        return None
    for name, power in _SMOOTHIE_POWER.findall(text):
        if name in readings:
            readings[name][2] = int(power)
    for name, power in _POWER.findall(text):
        key = name or "T"
        if key in readings:
            readings[key][2] = int(float(power))
        elif key == "T" and "T0" in readings:
            readings["T0"][2] = int(float(power))
    return Temperatures(tuple(HeaterReading(n, c, t, p) for n, (c, t, p) in readings.items()))


def _parse_ok(rest: str) -> Ok:
    position = _OK_POSITION.match(rest)
    if position:
        x, y, z, e = position.groups()
        return Ok(text=rest.strip(), position=Position(float(x), float(y), float(z),
                                                       float(e) if e is not None else None))
    temperatures = parse_temperatures(rest) if ("T:" in rest or "B:" in rest) else None
    fields: dict[str, int] = {}
    if temperatures is None:
        for key, value in _OK_FIELD.findall(rest):
            fields.setdefault(key, int(value))
        bare = _BARE_NUMBER.match(rest)
        if bare and "N" not in fields:
            fields["N"] = int(bare.group(1))  # Repetier: "ok 123"
    return Ok(
        line=fields.get("N"),
        planner_free=fields.get("P"),
        queue_free=fields.get("B"),
        temperatures=temperatures,
        text=rest.strip(),
    )


#: Words of a heater error after which the firmware has turned its heaters off and stopped: Marlin
#: and Prusa ("Thermal Runaway", "MINTEMP", "MAXTEMP", "Heating failed"), Smoothieware ("Temperature
#: runaway", "took too long to be reached"), Repetier ("Heater decoupled", "Heater/sensor error") and
#: RepRapFirmware ("Heater 1 fault").
_THERMAL_WORDS = ("thermal runaway", "maxtemp", "mintemp", "heating failed", "temperature runaway",
                  "too long to be reached", "heater decoupled", "heater/sensor error")
_HEATER_FAULT = re.compile(r"\bheater \d+ fault\b", re.IGNORECASE)


def _last_line(message: str) -> int | None:
    """The last line the printer took: Marlin's "Last Line: 41", Repetier's "expected line 42"."""
    match = _LAST_LINE.search(message)
    if match:
        return int(match.group(1))
    match = _EXPECTED_LINE.search(message)
    return int(match.group(1)) - 1 if match else None


def _line_check_kind(lower: str) -> str | None:
    """The line check an error reports (Marlin's, Prusa's and Repetier's words), if any."""
    if "checksum mismatch" in lower or "wrong checksum" in lower:
        return ErrorKind.CHECKSUM
    if "line number is not" in lower or "expected line" in lower:
        return ErrorKind.LINE_NUMBER
    if "no checksum" in lower or "missing checksum" in lower:
        return ErrorKind.NO_CHECKSUM
    if "no line number" in lower:
        return ErrorKind.NO_LINE_NUMBER
    return None


def _parse_error(message: str, fatal: bool = False) -> Error:
    """An error line's text; ``fatal``: the prefix alone says the printer stopped (``fatal:``)."""
    lower = message.lower()
    last_line = _last_line(message)
    kind = _line_check_kind(lower)
    if kind is not None:
        return Error(message, kind, last_line)
    if any(word in lower for word in _THERMAL_WORDS) or _HEATER_FAULT.search(message):
        return Error(message, ErrorKind.THERMAL, last_line, fatal=True)
    if "kill() called" in lower or "halted" in lower or _HALT_LINE.search(message):
        return Error(message, ErrorKind.HALTED, last_line, fatal=True)
    if "printer stopped" in lower or "stopped due to errors" in lower or fatal:
        return Error(message, ErrorKind.STOPPED, last_line, fatal=True)
    return Error(message, ErrorKind.OTHER, last_line)


def parse_line(raw: str) -> Event:
    """Parse one line received from the printer (without its line terminator) into an event.

    Every input gives an event; a line nothing recognises becomes :class:`Other`.
    """
    line = raw.strip()
    lower = line.lower()
    if lower == "ok" or lower.startswith("ok ") or lower.startswith("ok:"):
        return _parse_ok(line[2:].lstrip(": "))
    if lower.startswith("resend") or lower.startswith("rs ") or lower.startswith("rs:"):
        match = _RESEND.match(line)
        if match:
            return Resend(int(match.group(1)))
        return Other(line)
    if lower.startswith("error:") or lower.startswith("fatal:"):
        return _parse_error(line[6:].strip(), fatal=lower.startswith("fatal:"))
    if lower.startswith("!!"):
        # Smoothieware answers every command with a bare "!!" while halted (GcodeDispatch.cpp);
        # Klipper puts "!! " before an error message that does not stop it.
        message = line[2:].strip()
        return Error("halted (!!)", ErrorKind.HALTED, fatal=True) if not message else _parse_error(message)
    if _HALT_LINE.search(line):
        return _parse_error(line)
    if lower == "start":
        return Start()
    if lower == "wait":
        return Wait()
    skip = _SKIP.match(line)
    if skip:
        return Skip(int(skip.group(1)))
    if lower.startswith("//action:"):
        return Action(line[len("//action:") :].strip())
    body = line[5:].strip() if lower.startswith("echo:") else line
    body_lower = body.lower()
    if body_lower.startswith("busy:"):
        return Busy(body[5:].strip())
    if body_lower.startswith("unknown command:"):
        command = body[len("unknown command:") :].strip().strip('"')
        return UnknownCommand(command)
    factor = _SPEED_FACTOR.match(body) or _FLOW_FACTOR.match(body)
    if factor:
        return Factor("speed" if body.startswith("FR") else "flow", float(factor.group(1)))
    if lower.startswith("echo:"):
        return Echo(body)
    for prefix in ("info:", "warning:"):  # Repetier's "Info:PowerUp", RepRapFirmware's warnings
        if lower.startswith(prefix):
            return Echo(line[len(prefix):].strip())
    if line.startswith("FIRMWARE_NAME:"):
        return FirmwareInfo(_split_firmware_fields(line))
    if line.startswith("Cap:"):
        parts = line[4:].rsplit(":", 1)
        if len(parts) == 2 and parts[1].strip() in ("0", "1"):
            return Capability(parts[0].strip().upper(), parts[1].strip() == "1")
        return Other(line)
    position = _POSITION.match(line)
    if position:
        x, y, z, e = (float(v) for v in position.groups())
        return Position(x, y, z, e)
    if line.startswith(("T:", "T0:", "B:")):
        temperatures = parse_temperatures(line)
        if temperatures is not None:
            return TemperatureReport(temperatures, waiting=" W:" in line)
    return Other(line)


def _split_firmware_fields(line: str) -> dict[str, str]:
    """Split ``FIRMWARE_NAME:Marlin 2.1 (…) SOURCE_CODE_URL:… UUID:…`` into its fields.

    Values may contain spaces (the firmware name does) and colons (a URL, a time), so a key is an
    upper-case word followed by ``:`` at the start or after a space or comma; a value ends where the
    next key starts, without the space or comma before it.
    """
    marks = list(_FIRMWARE_FIELD.finditer(line))
    fields: dict[str, str] = {}
    for i, mark in enumerate(marks):
        end = marks[i + 1].start() if i + 1 < len(marks) else len(line)
        fields.setdefault(mark.group(1), line[mark.end() : end].strip().rstrip(",").strip())
    return fields
