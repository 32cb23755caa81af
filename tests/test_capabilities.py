"""The capabilities object learns the dialect from M115's FIRMWARE_NAME and takes its facts.

The FIRMWARE_NAME values are the firmwares' own (see tests/test_codec_dialects.py for their
sources); the facts expected of each dialect are what its source shows (cited in
``ribbond.printer.capabilities.DIALECTS`` and below), so each row states the firmware's behaviour,
not the table's content read back.
"""

from __future__ import annotations

import pytest

from ribbond.printer import codec
from ribbond.printer.capabilities import DIALECTS, Capabilities, dialect_for

NAMES = [
    ("Marlin 2.1.2.1 (May 25 2023 10:00:00)", "marlin2"),
    ("Marlin bugfix-2.1.x (Jan 23 2023 23:25:27)", "marlin2"),
    ("Marlin 2.0.8.26F4", "marlin2"),
    ("Marlin 1.1.9 (Github)", "marlin1"),
    ("Marlin V1; Sprinter/grbl mashup for gen6", "marlin1"),
    ("Marlin", "marlin2"),                                              # no version: today's Marlin
    ("Prusa-Firmware 3.8.1 based on Marlin", "prusa"),                 # not Marlin: "based on"
    ("Prusa-Firmware-Buddy 5.1.2+13478 (Github)", "marlin2"),          # MK4/XL: Marlin 2 inside
    ("RepRapFirmware for Duet 2 WiFi/Ethernet", "reprapfirmware"),
    ("RepRapFirmware for Duet 3 MB6HC", "reprapfirmware"),
    ("Smoothieware", "smoothieware"),
    ("Repetier_1.0.4", "repetier"),
    ("Klipper", "klipper"),
    ("Teacup", None),
    ("", None),
]


@pytest.mark.parametrize("name, dialect", NAMES)
def test_the_dialect_comes_from_the_firmware_name(name: str, dialect: str | None) -> None:
    assert dialect_for(name) == dialect


# What each firmware does, from its source (the row's reason in the comment):
# (dialect, ok after a resend request, where M114's position comes, when ok comes, empty line answered,
#  a bad line, "wait" means idle, what M112 leaves, the stop's bytes)
FACTS = [
    # Marlin 1.1.x FlushSerialRequestResend() ends with ok_to_send(); M114's report before its ok
    ("marlin1", True, "line", "processed", False, "resend", False, "halts", b"M112\n"),
    # queue.cpp flush_and_request_resend() prints STR_OK after the request
    ("marlin2", True, "line", "processed", False, "resend", False, "halts", b"M112\n"),
    # Prusa's FlushSerialRequestResend() "…\n%S\n" with MSG_OK; kill() ends in softReset()
    ("prusa", True, "line", "processed", False, "resend", False, "reboots", b"M112\n"),
    # RRF 3 StringParser::LineFinished() drops a bad line (no request, so no ok after one)
    ("reprapfirmware", False, "line", "processed", False, "discarded", False, "halts", b"M112\n"),
    # GcodeDispatch.cpp: "rs N%d" without ok, "ok %s" with M114's text, "ok" to an empty line;
    # SerialConsole.cpp: Ctrl-X halts as it arrives
    ("smoothieware", False, "ok", "processed", True, "resend", False, "halts", b"\x18"),
    # gcode.cpp: requestResend() prints ok; checkAndPushCommand() acknowledges on receipt;
    # readFromSerial() prints "wait"; Commands::emergencyStop() with KILL_METHOD 1 resets the board
    ("repetier", True, "line", "received", False, "resend", True, "reboots", b"M112\n"),
]


@pytest.mark.parametrize("dialect, resend_ok, position, ok_means, empty, bad, wait, stop, stop_bytes", FACTS)
def test_learning_a_firmware_takes_its_dialects_facts(dialect: str, resend_ok: bool, position: str,
                                                     ok_means: str, empty: bool, bad: str, wait: bool,
                                                     stop: str, stop_bytes: bytes) -> None:
    name = next(n for n, d in NAMES if d == dialect)
    caps = Capabilities()
    caps.learn_firmware(codec.FirmwareInfo({"FIRMWARE_NAME": name}))
    assert caps.dialect == dialect and caps.firmware_name == name
    assert (caps.ok_after_resend, caps.position_report, caps.ok_means, caps.answers_empty_line,
            caps.bad_lines, caps.says_wait, caps.emergency_stop, caps.stop_bytes) == (
        resend_ok, position, ok_means, empty, bad, wait, stop, stop_bytes)


def test_the_table_has_every_simulated_dialect_and_no_name_twice() -> None:
    assert {"marlin1", "marlin2", "prusa", "reprapfirmware", "smoothieware", "repetier"} <= set(DIALECTS)
    assert len({d.label for d in DIALECTS.values()}) == len(DIALECTS)


def test_an_operators_explicit_setting_survives_the_dialect() -> None:
    """``--no-ok-after-resend`` (or a test's Capabilities(ok_after_resend=False)) is kept when M115
    names a firmware whose dialect says otherwise; the other facts follow the dialect."""
    caps = Capabilities(ok_after_resend=False)
    copy = caps.model_copy(deep=True)                      # the link works on a copy
    copy.learn_firmware(codec.FirmwareInfo({"FIRMWARE_NAME": "Repetier_1.0.4"}))
    assert copy.ok_after_resend is False and copy.ok_means == "received"


def test_an_unknown_firmware_keeps_the_dialect_it_had() -> None:
    caps = Capabilities()
    caps.use_dialect("smoothieware")
    caps.learn_firmware(codec.FirmwareInfo({"FIRMWARE_NAME": "Teacup"}))
    assert caps.dialect == "smoothieware" and caps.firmware_name == "Teacup"


def test_capabilities_the_firmware_reports_decide_autoreport_and_the_emergency_parser() -> None:
    """M155 is used only where the dialect has it and the firmware reports Cap:AUTOREPORT_TEMP:1;
    the stop acts at once where Cap:EMERGENCY_PARSER:1 says so, or where the dialect's stop is
    immediate (Smoothieware's Ctrl-X) whatever the Cap lines."""
    marlin = Capabilities()
    assert not marlin.autoreport_temperatures and not marlin.emergency_parser
    marlin.learn_capability(codec.Capability("AUTOREPORT_TEMP", True))
    marlin.learn_capability(codec.Capability("EMERGENCY_PARSER", True))
    assert marlin.autoreport_temperatures and marlin.emergency_parser
    rrf = Capabilities()
    rrf.use_dialect("reprapfirmware")
    rrf.learn_capability(codec.Capability("AUTOREPORT_TEMP", True))
    assert not rrf.autoreport_temperatures, "RepRapFirmware's USB Marlin mode has no M155"
    smoothie = Capabilities()
    smoothie.use_dialect("smoothieware")
    assert smoothie.emergency_parser


def test_acknowledgements_teach_advanced_ok_slots_and_the_position_report() -> None:
    caps = Capabilities()
    caps.learn_ok(codec.Ok())
    assert not caps.advanced_ok and caps.queue_slots == 4
    caps.learn_ok(codec.Ok(line=3, planner_free=15, queue_free=7))
    assert caps.advanced_ok and caps.queue_slots == 8 and caps.planner_blocks == 16
    caps.learn_ok(codec.Ok(position=codec.Position(1.0, 2.0, 3.0)))
    assert caps.position_report == "ok"
