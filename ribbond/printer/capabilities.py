"""What the firmware on the other end can do, in one typed object.

Firmwares differ in ways a host must know. Some differences come with the firmware's family, its
*dialect* (Marlin 1.x or 2.x, Prusa, RepRapFirmware, Smoothieware, Repetier): whether an ``ok``
follows a resend request, when an ``ok`` comes (Repetier acknowledges a line when it has received
it, the others once they have processed it), where ``M114``'s position is printed, whether an empty
line is answered, what becomes of a line that fails its checks, whether ``wait`` means idle, what
``M112`` leaves behind. They are data in :data:`DIALECTS`, one row per dialect, chosen from ``M115``'s
``FIRMWARE_NAME`` (:func:`dialect_for`). Others are learned from the firmware itself: its ``Cap:``
lines, ADVANCED_OK (which Marlin does not list in ``M115``: it is learned from the first
acknowledgement that carries ``P``/``B``), the slot counts. Everything the link and the sender do
differently per firmware reads this object; nothing else keeps firmware flags or names.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr

from . import codec
from .window import SAFE_WINDOW

DialectName = Literal["marlin1", "marlin2", "prusa", "reprapfirmware", "smoothieware", "repetier", "klipper"]


@dataclass(frozen=True)
class Dialect:
    """How one firmware family speaks the serial protocol, as far as a streaming host must know.

    Each fact comes from the firmware's source, cited in ``source`` (and line by line in
    ``tests/test_codec_dialects.py`` and ``tests/test_capabilities.py``).
    """

    name: DialectName
    label: str
    #: A plain ``ok`` follows every resend request (Marlin, Prusa, Repetier), so it acknowledges nothing.
    ok_after_resend: bool
    #: How it asks for a line again (for people reading logs; the codec takes every form).
    resend_form: str
    #: Where ``M114``'s position comes: its own line before the ``ok`` ("line") or on it ("ok").
    position_report: Literal["line", "ok"]
    #: When the ``ok`` comes: once the command was processed (a move: once it is planned), or as
    #: soon as the line was received into the command buffer (Repetier): then a report printed
    #: when a later query runs is what proves that a command has run.
    ok_means: Literal["processed", "received"]
    #: An empty line is answered with ``ok`` (Smoothieware): the sender must never send one.
    answers_empty_line: bool
    #: A line that fails its checks is asked for again ("resend") or dropped without a word
    #: (RepRapFirmware 3: no resend request, and line numbers are not checked).
    bad_lines: Literal["resend", "discarded"]
    #: ``wait`` is printed when the command buffer has been empty for a second (Repetier).
    says_wait: bool
    #: The firmware has ``M155`` temperature autoreports (used only when ``Cap:AUTOREPORT_TEMP:1``).
    m155: bool
    #: What ``M112`` leaves: halted until ``M999``/a reset ("halts"), or a board that reboots.
    emergency_stop: Literal["halts", "reboots"]
    #: What the link writes for the emergency stop: ``M112`` as a line, or Smoothieware's Ctrl-X.
    stop_bytes: bytes
    #: The stop acts at once, ahead of queued commands (None: ``Cap:EMERGENCY_PARSER`` says).
    immediate_stop: bool | None
    source: str


_MARLIN_SOURCE = ("MarlinFirmware/Marlin: Marlin/src/gcode/queue.cpp (ok_to_send, gcode_line_error, "
                  "flush_and_request_resend)")

DIALECTS: dict[str, Dialect] = {d.name: d for d in (
    Dialect("marlin1", "Marlin 1.x", ok_after_resend=True, resend_form="Resend: N", position_report="line",
            ok_means="processed", answers_empty_line=False, bad_lines="resend", says_wait=False, m155=True,
            emergency_stop="halts", stop_bytes=b"M112\n", immediate_stop=None,
            source="MarlinFirmware/Marlin 1.1.x: Marlin/Marlin_main.cpp (FlushSerialRequestResend, get_serial_commands)"),
    Dialect("marlin2", "Marlin 2.x", ok_after_resend=True, resend_form="Resend: N", position_report="line",
            ok_means="processed", answers_empty_line=False, bad_lines="resend", says_wait=False, m155=True,
            emergency_stop="halts", stop_bytes=b"M112\n", immediate_stop=None, source=_MARLIN_SOURCE),
    Dialect("prusa", "Prusa firmware (MK3)", ok_after_resend=True, resend_form="Resend: N",
            position_report="line", ok_means="processed", answers_empty_line=False, bad_lines="resend",
            says_wait=False, m155=True, emergency_stop="reboots", stop_bytes=b"M112\n", immediate_stop=None,
            source="prusa3d/Prusa-Firmware: Firmware/Marlin_main.cpp (FlushSerialRequestResend, kill), "
                   "Firmware/cmdqueue.cpp"),
    Dialect("reprapfirmware", "RepRapFirmware", ok_after_resend=False, resend_form="(none in 3.x; 2.x: rs N)",
            position_report="line", ok_means="processed", answers_empty_line=False, bad_lines="discarded",
            says_wait=False, m155=False, emergency_stop="halts", stop_bytes=b"M112\n", immediate_stop=None,
            source="Duet3D/RepRapFirmware: src/GCodes/GCodeBuffer/StringParser.cpp (LineFinished), "
                   "src/GCodes/GCodes.cpp (HandleReply, DoEmergencyStop)"),
    Dialect("smoothieware", "Smoothieware", ok_after_resend=False, resend_form="rs N<line>", position_report="ok",
            ok_means="processed", answers_empty_line=True, bad_lines="resend", says_wait=False, m155=False,
            emergency_stop="halts", stop_bytes=b"\x18", immediate_stop=True,
            source="Smoothieware/Smoothieware: src/modules/communication/GcodeDispatch.cpp "
                   "(on_console_line_received), src/modules/communication/SerialConsole.cpp (Ctrl-X)"),
    Dialect("repetier", "Repetier", ok_after_resend=True, resend_form="Resend:N", position_report="line",
            ok_means="received", answers_empty_line=False, bad_lines="resend", says_wait=True, m155=True,
            emergency_stop="reboots", stop_bytes=b"M112\n", immediate_stop=None,
            source="repetier/Repetier-Firmware: src/ArduinoAVR/Repetier/gcode.cpp (checkAndPushCommand, "
                   "requestResend, readFromSerial), Commands.cpp (emergencyStop)"),
    # Not simulated; kept from before: it answers a resend request (if ever) without an ok.
    Dialect("klipper", "Klipper", ok_after_resend=False, resend_form="(none)", position_report="line",
            ok_means="processed", answers_empty_line=False, bad_lines="resend", says_wait=False, m155=False,
            emergency_stop="halts", stop_bytes=b"M112\n", immediate_stop=None, source="Klipper3d/klipper"),
)}

#: Capabilities' fields a dialect sets (unless given when the object was made, or learned since).
DIALECT_FIELDS = ("ok_after_resend", "position_report", "ok_means", "answers_empty_line", "bad_lines",
                  "says_wait", "m155", "emergency_stop", "stop_bytes", "immediate_stop")

_MARLIN_VERSION = re.compile(r"\bmarlin\s+(?:bugfix-)?v?(\d+)", re.IGNORECASE)


def dialect_for(firmware_name: str) -> DialectName | None:
    """The dialect of a ``FIRMWARE_NAME``, or None when the firmware is not one we know.

    Prusa's MK3 firmware calls itself "Prusa-Firmware 3.x based on Marlin" (so it is looked for
    before Marlin); Prusa's Buddy firmware (MK4, XL) is Marlin 2 inside and speaks as Marlin 2.x.
    """
    lowered = firmware_name.strip().lower()
    if lowered.startswith("prusa-firmware-buddy"):
        return "marlin2"
    if lowered.startswith("prusa-firmware"):
        return "prusa"
    if "reprapfirmware" in lowered:
        return "reprapfirmware"
    if "smoothie" in lowered:
        return "smoothieware"
    if lowered.startswith("repetier"):
        return "repetier"
    if "klipper" in lowered:
        return "klipper"
    if "marlin" in lowered:
        version = _MARLIN_VERSION.search(firmware_name)
        return "marlin1" if version is not None and version.group(1) == "1" else "marlin2"
    return None


class Capabilities(BaseModel):
    """Firmware capabilities: defaults are Marlin 2.x's stock configuration.

    Fields a dialect sets (:data:`DIALECT_FIELDS`) keep a value given when the object is made: an
    operator's explicit setting is not undone by what ``M115`` says.
    """

    model_config = ConfigDict(validate_assignment=True)

    firmware_name: str = ""
    firmware_fields: dict[str, str] = Field(default_factory=dict)
    #: The firmware's family (:data:`DIALECTS`), from ``M115``'s ``FIRMWARE_NAME``.
    dialect: DialectName = "marlin2"
    #: ``Cap:`` lines of ``M115``; a capability not reported is absent.
    reported: dict[str, bool] = Field(default_factory=dict)
    #: Learned from the acknowledgements themselves.
    advanced_ok: bool = False
    #: Bytes the host lets be unacknowledged, counted as if all were still in the printer's receive
    #: buffer (they are when the firmware is blocked in a long command). Marlin's RX_BUFFER_SIZE is
    #: 128 by default, but boards with 64 bytes exist and nothing in M115 tells: the default is the
    #: window safe for them (``window.SAFE_WINDOW``); set 127 for a board known to have 128. A
    #: window found too large is shrunk while streaming (``window.WindowGovernor``).
    rx_buffer_bytes: int = Field(default=SAFE_WINDOW, ge=16, le=65536)
    #: Command queue slots (Marlin's BUFSIZE). Raised when ADVANCED_OK reports more free slots.
    queue_slots: int = Field(default=4, ge=1, le=64)
    #: Planner blocks (Marlin's BLOCK_BUFFER_SIZE), learned from the largest ``P`` seen + 1.
    planner_blocks: int | None = None
    # ---- set by the dialect (see Dialect for what each means)
    ok_after_resend: bool = True
    #: Learned at connect from the answer to ``M114`` (``learn_position_report``), whatever the
    #: firmware's name says: some builds print a command's output after its ``ok`` ("after_ok").
    #: An ``ok`` with the position carries no ``N``/``P``/``B``, and the sender takes it as ``M114``'s own.
    position_report: Literal["line", "ok", "after_ok"] = "line"
    ok_means: Literal["processed", "received"] = "processed"
    answers_empty_line: bool = False
    bad_lines: Literal["resend", "discarded"] = "resend"
    says_wait: bool = False
    m155: bool = True
    emergency_stop: Literal["halts", "reboots"] = "halts"
    stop_bytes: bytes = b"M112\n"
    immediate_stop: bool | None = None

    _pinned: frozenset[str] = PrivateAttr(default=frozenset())

    def model_post_init(self, context: Any) -> None:
        self._pinned = frozenset(self.model_fields_set & set(DIALECT_FIELDS))

    def has(self, name: str) -> bool:
        """True only when the firmware reported ``Cap:<name>:1``."""
        return self.reported.get(name.upper(), False)

    @property
    def spec(self) -> Dialect:
        """The dialect's row of :data:`DIALECTS`."""
        return DIALECTS[self.dialect]

    @property
    def autoreport_temperatures(self) -> bool:
        return self.m155 and self.has("AUTOREPORT_TEMP")

    @property
    def emergency_parser(self) -> bool:
        """Whether the emergency stop acts at once, ahead of the commands already queued."""
        return self.immediate_stop if self.immediate_stop is not None else self.has("EMERGENCY_PARSER")

    def use_dialect(self, name: DialectName) -> None:
        """Take a dialect's facts (except those pinned when this object was made)."""
        spec = DIALECTS[name]
        self.dialect = name
        for field in DIALECT_FIELDS:
            if field not in self._pinned:
                setattr(self, field, getattr(spec, field))

    def learn_firmware(self, info: codec.FirmwareInfo) -> None:
        """Take the ``FIRMWARE_NAME`` line of ``M115`` and the dialect it names (an unknown firmware
        keeps the dialect this object has)."""
        self.firmware_fields = dict(info.fields)
        self.firmware_name = info.name
        dialect = dialect_for(info.name)
        if dialect is not None:
            self.use_dialect(dialect)

    def learn_capability(self, cap: codec.Capability) -> None:
        """Take one ``Cap:`` line of ``M115``."""
        self.reported = {**self.reported, cap.name: cap.enabled}

    def learn_position_report(self, before_ok: bool, on_ok: bool, after_ok: bool) -> None:
        """Where the answer to an ``M114`` put the position: on a line before its ``ok``, on the
        ``ok`` line, or on a line after it (nowhere: the dialect's row stays)."""
        if on_ok:
            self.position_report = "ok"
        elif before_ok:
            self.position_report = "line"
        elif after_ok:
            self.position_report = "after_ok"

    def learn_ok(self, ok: codec.Ok) -> None:
        """Take what an acknowledgement tells about the firmware (ADVANCED_OK and slot counts,
        where ``M114`` puts the position)."""
        if ok.position is not None and self.position_report != "ok":
            self.position_report = "ok"
        if ok.queue_free is None or ok.planner_free is None:
            return
        if not self.advanced_ok:
            self.advanced_ok = True
        # B counts the acknowledged command as still queued, so the queue has at least B + 1 slots.
        if ok.queue_free + 1 > self.queue_slots:
            self.queue_slots = ok.queue_free + 1
        if self.planner_blocks is None or ok.planner_free + 1 > self.planner_blocks:
            self.planner_blocks = ok.planner_free + 1
