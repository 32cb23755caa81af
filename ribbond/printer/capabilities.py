"""What the firmware on the other end can do, in one typed object.

Firmwares differ in ways a host must know: whether acknowledgements carry the free planner and
queue slots (ADVANCED_OK, which Marlin does not list in ``M115``: it is learned from the first
acknowledgement that carries ``P``/``B``), whether an ``ok`` follows a resend request, how large the
receive buffer and command queue are, whether temperatures can be autoreported and whether ``M112``
is acted on immediately. Everything the link does differently per firmware reads this object;
nothing else keeps firmware flags.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from . import codec
from .window import SAFE_WINDOW


class Capabilities(BaseModel):
    """Firmware capabilities: defaults are Marlin 2.x's stock configuration."""

    model_config = ConfigDict(validate_assignment=True)

    firmware_name: str = ""
    firmware_fields: dict[str, str] = Field(default_factory=dict)
    #: ``Cap:`` lines of ``M115``; a capability not reported is absent.
    reported: dict[str, bool] = Field(default_factory=dict)
    #: Learned from the acknowledgements themselves.
    advanced_ok: bool = False
    #: Marlin (and Prusa, Repetier) send a plain ``ok`` after every ``Resend:``.
    ok_after_resend: bool = True
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
    #: Where ``M114``'s position comes: "line" (its own line before the ``ok``, Marlin) or "ok"
    #: (on the ``ok`` line, Smoothieware: ``ok C: X:… Y:… Z:…``); learned from the first answer.
    #: Such an ``ok`` carries no ``N``/``P``/``B``: the sender takes it as ``M114``'s own.
    position_report: Literal["line", "ok"] = "line"

    def has(self, name: str) -> bool:
        """True only when the firmware reported ``Cap:<name>:1``."""
        return self.reported.get(name.upper(), False)

    @property
    def autoreport_temperatures(self) -> bool:
        return self.has("AUTOREPORT_TEMP")

    @property
    def emergency_parser(self) -> bool:
        return self.has("EMERGENCY_PARSER")

    def learn_firmware(self, info: codec.FirmwareInfo) -> None:
        """Take the ``FIRMWARE_NAME`` line of ``M115``."""
        self.firmware_fields = dict(info.fields)
        self.firmware_name = info.name
        # Smoothieware and Klipper answer a resend request (if ever) without an extra ok.
        lowered = info.name.lower()
        if "smoothie" in lowered or "klipper" in lowered:
            self.ok_after_resend = False

    def learn_capability(self, cap: codec.Capability) -> None:
        """Take one ``Cap:`` line of ``M115``."""
        self.reported = {**self.reported, cap.name: cap.enabled}

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
