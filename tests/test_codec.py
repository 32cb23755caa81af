"""The Marlin codec on tables of answer lines as real firmwares print them."""

from __future__ import annotations

from functools import reduce

import pytest

from ribbond.printer import codec
from ribbond.printer.codec import ErrorKind


def xor(text: str) -> int:
    """The protocol's checksum, written independently of the codec."""
    return reduce(lambda a, b: a ^ b, text.encode(), 0)


# ------------------------------------------------------------------ encoding


@pytest.mark.parametrize("number, command", [
    (0, "M110 N0"), (1, "G28"), (41, "G1 X10.5 Y-3 E0.1234 F1800"), (123456, "M104 S210"),
])
def test_encode_numbers_and_checksums_lines(number: int, command: str) -> None:
    body = f"N{number} {command}"
    assert codec.encode(number, command) == f"{body}*{xor(body)}\n".encode()


def test_encode_rejects_what_the_firmware_would_mangle() -> None:
    with pytest.raises(ValueError, match="95"):
        codec.encode(1, "G1 " + "X1.0000 " * 12)
    for bad in ("", "   ", "G1 X1*5", "G1\nG28", "M117 café"):
        with pytest.raises(ValueError):
            codec.encode(1, bad)


def command_encoding_to(length: int, number: int = 1) -> str:
    """An ``M117`` command whose numbered line ``N<number> M117 …*<checksum>`` is exactly ``length``
    characters long (the checksum's digits depend on the text: try each message length)."""
    for filler in range(length, 0, -1):
        command = "M117 " + "a" * filler
        body = f"N{number} {command}"
        if len(f"{body}*{xor(body)}") == length:
            return command
    raise AssertionError(f"no M117 line of {length} characters")


# Marlin's MAX_CMD_SIZE is 96 bytes with the terminating NUL: 95 characters fit, a 96th is cut off.
def test_a_95_character_line_is_encoded_whole() -> None:
    command = command_encoding_to(95)
    text = codec.encode(1, command).decode()
    assert len(text) == 96 and text.endswith("\n"), "95 characters and the newline"
    assert text == f"N1 {command}*{xor(f'N1 {command}')}\n"


def test_a_96_character_line_is_refused_naming_the_limit() -> None:
    command = command_encoding_to(96)
    with pytest.raises(ValueError, match=r"encodes to 96 characters; the firmware's limit is 95"):
        codec.encode(1, command)


def test_check_sendable_leaves_room_for_the_widest_line_number() -> None:
    """A command is checked with the widest line number a session reaches (9 999 999): one that
    fits at line 1 but not there is refused before it is queued."""
    fits_at_line_1 = command_encoding_to(95)
    with pytest.raises(ValueError, match="limit is 95"):
        codec.check_sendable(fits_at_line_1)
    codec.check_sendable(command_encoding_to(95, number=9_999_999))


def test_strip_comment() -> None:
    assert codec.strip_comment("G1 X1 ; move") == "G1 X1"
    assert codec.strip_comment("G1 (inline) X1") == "G1  X1"
    assert codec.strip_comment(";TYPE:WALL-OUTER") == ""
    assert codec.strip_comment("   ") == ""


def test_unnumbered_emergency_line() -> None:
    assert codec.encode_unnumbered("M112") == b"M112\n"


# ------------------------------------------------------------------ acknowledgements

OK_TABLE = [
    # line as printed, firmware, expected (line, planner_free, queue_free)
    ("ok", "Marlin", (None, None, None)),
    ("ok N123 P15 B3", "Marlin ADVANCED_OK", (123, 15, 3)),
    ("ok N0 P15 B3", "Marlin ADVANCED_OK after M110", (0, 15, 3)),
    ("ok P15 B3", "Marlin ADVANCED_OK, unnumbered command", (None, 15, 3)),
    ("ok N5 P0 B0", "Marlin, planner and queue full", (5, 0, 0)),
    ("ok 1234", "Repetier with line numbers in ok", (1234, None, None)),
    ("ok ", "trailing space", (None, None, None)),
    ("OK", "upper case (some clones)", (None, None, None)),
]


@pytest.mark.parametrize("line, firmware, expected", OK_TABLE)
def test_ok_variants(line: str, firmware: str, expected: tuple) -> None:
    event = codec.parse_line(line)
    assert isinstance(event, codec.Ok), firmware
    assert (event.line, event.planner_free, event.queue_free) == expected
    assert event.advanced == (expected[1] is not None)


TEMPERATURE_OK_TABLE = [
    ("ok T:210.00 /210.00 B:60.00 /60.00 @:64 B@:0", {"T": (210.0, 210.0, 64), "B": (60.0, 60.0, 0)}),
    ("ok T:21.3 /0.0 B:20.9 /0.0 T0:21.3 /0.0 @:0 B@:0 P:0.0 A:26.4",  # Prusa
     {"T": (21.3, 0.0, 0), "B": (20.9, 0.0, 0), "T0": (21.3, 0.0, None)}),
    ("ok B:22.9 /0.0 T0:23.1 /0.0", {"B": (22.9, 0.0, None), "T0": (23.1, 0.0, None)}),  # Klipper
    ("ok T:25.1 /0.0 B:24.8 /0.0", {"T": (25.1, 0.0, None), "B": (24.8, 0.0, None)}),  # RepRapFirmware
]


@pytest.mark.parametrize("line, heaters", TEMPERATURE_OK_TABLE)
def test_ok_with_temperatures_is_no_advanced_ok(line: str, heaters: dict) -> None:
    event = codec.parse_line(line)
    assert isinstance(event, codec.Ok)
    assert event.temperatures is not None
    assert not event.advanced and event.line is None
    for name, (current, target, power) in heaters.items():
        reading = event.temperatures.get(name)
        assert reading is not None, name
        assert (reading.current, reading.target) == (current, target)
        if power is not None:
            assert reading.power == power


# ------------------------------------------------------------------ resends and errors

RESEND_TABLE = [
    ("Resend: 42", 42),  # Marlin, Prusa
    ("Resend:42", 42),  # Repetier
    ("resend 42", 42),
    ("rs 42", 42),  # Teacup, Repetier
    ("rs N42", 42),  # Smoothieware
    ("rs: 42", 42),
]


@pytest.mark.parametrize("line, number", RESEND_TABLE)
def test_resend_variants(line: str, number: int) -> None:
    assert codec.parse_line(line) == codec.Resend(number)


ERROR_TABLE = [
    ("Error:checksum mismatch, Last Line: 41", ErrorKind.CHECKSUM, 41, False),
    ("Error:Line Number is not Last Line Number+1, Last Line: 41", ErrorKind.LINE_NUMBER, 41, False),
    ("Error:No Checksum with line number, Last Line: 12", ErrorKind.NO_CHECKSUM, 12, False),
    ("Error:No Line Number with checksum, Last Line: 7", ErrorKind.NO_LINE_NUMBER, 7, False),
    ("Error:Printer halted. kill() called!", ErrorKind.HALTED, None, True),
    ("Error:Thermal Runaway, system stopped! Heater_ID: 0", ErrorKind.THERMAL, None, True),
    ("Error:Thermal Runaway, system stopped! Heater_ID: bed", ErrorKind.THERMAL, None, True),
    ("Error:MAXTEMP triggered, system stopped! Heater_ID: 0", ErrorKind.THERMAL, None, True),
    ("Error:Heating failed, system stopped! Heater_ID: 0", ErrorKind.THERMAL, None, True),
    # Marlin 2.x temperature.cpp _temp_error(): SERIAL_ERROR_START ("Error:"), the message
    # (language.h STR_T_MINTEMP "MINTEMP triggered"), STR_STOPPED_HEATER (", system stopped!
    # Heater_ID: ") and the heater's index, or STR_HEATER_BED "bed"; then kill() prints
    # STR_ERR_KILLED "Printer halted. kill() called!".
    ("Error:MINTEMP triggered, system stopped! Heater_ID: 0", ErrorKind.THERMAL, None, True),
    ("Error:MINTEMP triggered, system stopped! Heater_ID: bed", ErrorKind.THERMAL, None, True),
    ("Error:MAXTEMP triggered, system stopped! Heater_ID: bed", ErrorKind.THERMAL, None, True),
    ("Error: Printer halted. kill() called!", ErrorKind.HALTED, None, True),
    ("Error:Printer stopped due to errors. Fix the error and use M999 to restart. "
     "(Temperature is reset. Set it after restarting)", ErrorKind.STOPPED, None, True),
    ("Error: G0/G1: insufficient axes homed", ErrorKind.OTHER, None, False),  # RepRapFirmware
    ("!! Must home axis first: 10.000 10.000 0.300 [0.000]", ErrorKind.OTHER, None, False),  # Klipper
]


@pytest.mark.parametrize("line, kind, last_line, fatal", ERROR_TABLE)
def test_error_lines(line: str, kind: str, last_line: int | None, fatal: bool) -> None:
    event = codec.parse_line(line)
    assert isinstance(event, codec.Error)
    assert (event.kind, event.last_line, event.fatal) == (kind, last_line, fatal)


# ------------------------------------------------------------------ everything else

def test_busy_lines() -> None:
    assert codec.parse_line("echo:busy: processing") == codec.Busy("processing")
    assert codec.parse_line("echo:busy: paused for user") == codec.Busy("paused for user")
    assert codec.parse_line("busy: processing") == codec.Busy("processing")  # Prusa
    assert codec.parse_line("echo:busy: paused for input") == codec.Busy("paused for input")


@pytest.mark.parametrize("line, waiting, hotend", [
    (" T:22.05 /0.00 B:21.97 /0.00 @:0 B@:0", False, (22.05, 0.0)),  # Marlin autoreport
    ("T:185.40 /210.00 B:59.90 /60.00 @:127 B@:0 W:?", True, (185.4, 210.0)),  # Marlin M109 wait
    (" T:201.3 /210.0 B:60.0 /60.0 @:83 B@:0 W:9", True, (201.3, 210.0)),
    ("T:20.36 /0 B:20.53 /0 B@:0 @:0", False, (20.36, 0.0)),  # Repetier
    ("T0:210.0 /210.0 T1:25.0 /0.0 B:60.0 /60.0 @:40 B@:0", False, (210.0, 210.0)),
])
def test_temperature_reports(line: str, waiting: bool, hotend: tuple[float, float]) -> None:
    event = codec.parse_line(line)
    assert isinstance(event, codec.TemperatureReport)
    assert event.waiting == waiting
    assert event.temperatures.hotend is not None
    assert (event.temperatures.hotend.current, event.temperatures.hotend.target) == hotend


def test_power_is_attached_to_its_heater() -> None:
    event = codec.parse_line("T:150.0 /210.0 B:40.0 /60.0 @:127 B@:90 W:?")
    assert isinstance(event, codec.TemperatureReport)
    assert event.temperatures.get("T").power == 127  # type: ignore[union-attr]
    assert event.temperatures.get("B").power == 90  # type: ignore[union-attr]


@pytest.mark.parametrize("line, xyze", [
    ("X:10.00 Y:20.00 Z:0.30 E:1.20 Count X:800 Y:1600 Z:120", (10.0, 20.0, 0.3, 1.2)),  # Marlin
    ("X:0.000 Y:0.000 Z:5.000 E:0.000", (0.0, 0.0, 5.0, 0.0)),  # Klipper
    ("X:1.000 Y:2.000 Z:3.000 E0:0.0 Count 80 160 1200 Machine 1.000 2.000 3.000", (1.0, 2.0, 3.0, 0.0)),  # RRF
    ("X:-5.50 Y:3.25 Z:10.00 E:-2.00 Count X:-440 Y:260 Z:4000", (-5.5, 3.25, 10.0, -2.0)),
])  # (Marlin's own line before its ok)
def test_position(line: str, xyze: tuple) -> None:
    event = codec.parse_line(line)
    assert isinstance(event, codec.Position)
    assert (event.x, event.y, event.z, event.e) == xyze


def test_firmware_info_fields_with_spaces() -> None:
    line = ("FIRMWARE_NAME:Marlin 2.1.2.1 (Jun 28 2023 10:00:00) SOURCE_CODE_URL:github.com/MarlinFirmware/Marlin "
            "PROTOCOL_VERSION:1.0 MACHINE_TYPE:Ender-3 V2 EXTRUDER_COUNT:1 UUID:cede2a2f-41a2-4748-9b12-c55c62f367ff")
    event = codec.parse_line(line)
    assert isinstance(event, codec.FirmwareInfo)
    assert event.name == "Marlin 2.1.2.1 (Jun 28 2023 10:00:00)"
    assert event.fields["MACHINE_TYPE"] == "Ender-3 V2"
    assert event.fields["EXTRUDER_COUNT"] == "1"
    klipper = codec.parse_line("FIRMWARE_NAME:Klipper FIRMWARE_VERSION:v0.12.0-114-ga77d0790")
    assert isinstance(klipper, codec.FirmwareInfo) and klipper.name == "Klipper"


@pytest.mark.parametrize("line, name, enabled", [
    ("Cap:AUTOREPORT_TEMP:1", "AUTOREPORT_TEMP", True),
    ("Cap:EMERGENCY_PARSER:0", "EMERGENCY_PARSER", False),
    ("Cap:SERIAL_XON_XOFF:0", "SERIAL_XON_XOFF", False),
])
def test_capabilities(line: str, name: str, enabled: bool) -> None:
    assert codec.parse_line(line) == codec.Capability(name, enabled)


def test_feed_override_and_flow_reports() -> None:
    """Marlin's M220 without words prints "FR:<n>%" (M220.cpp), M221 without S "echo:E<i> Flow: <n>%"
    (M221.cpp); an echo that only mentions a flow stays an echo."""
    assert codec.parse_line("FR:100%") == codec.Factor("speed", 100.0)
    assert codec.parse_line("FR:55%") == codec.Factor("speed", 55.0)
    assert codec.parse_line("echo:E0 Flow: 120%") == codec.Factor("flow", 120.0)
    assert codec.parse_line("echo:E1 Flow:95%") == codec.Factor("flow", 95.0)
    assert codec.parse_line("echo:Flow rate changed") == codec.Echo("Flow rate changed")
    assert codec.parse_line("FR:fast") == codec.Other("FR:fast")


def test_start_action_unknown_echo_other() -> None:
    assert codec.parse_line("start") == codec.Start()
    assert codec.parse_line("//action:pause") == codec.Action("pause")
    assert codec.parse_line("//action:notification Printing...") == codec.Action("notification Printing...")
    assert codec.parse_line('echo:Unknown command: "G999"') == codec.UnknownCommand("G999")
    assert codec.parse_line("echo:SD card ok") == codec.Echo("SD card ok")
    assert codec.parse_line("echo:  M92 X80.00 Y80.00 Z400.00 E93.00") == codec.Echo("M92 X80.00 Y80.00 Z400.00 E93.00")
    assert codec.parse_line("wait") == codec.Wait()  # Repetier idle (tests/test_codec_dialects.py)
    assert codec.parse_line("// Klipper state: Ready") == codec.Other("// Klipper state: Ready")
    assert codec.parse_line("\x00\xff garbage") == codec.Other("\x00\xff garbage")


ODD_LINES = [
    # line, the event it must give: fragments of real answers, cut or empty
    ("", codec.Other("")),
    (" ", codec.Other("")),
    ("ok:", codec.Ok()),
    ("Resend:", codec.Other("Resend:")),           # no number: nothing to resend
    ("Cap:", codec.Other("Cap:")),
    ("Cap:EEPROM", codec.Other("Cap:EEPROM")),      # no :0/:1
    ("T:", codec.Other("T:")),                      # no reading
    ("X:", codec.Other("X:")),                      # no position
    ("X:1.0 Y:2.0", codec.Other("X:1.0 Y:2.0")),    # cut before Z
    ("Error:", codec.Error("", ErrorKind.OTHER)),
    ("!!", codec.Error("halted (!!)", ErrorKind.HALTED, fatal=True)),  # Smoothieware, halted
    ("echo:", codec.Echo("")),
    ("rs", codec.Other("rs")),
    ("ok C:", codec.Ok(text="C:")),                 # a cut Smoothieware M114 answer: no position
]


@pytest.mark.parametrize("line, event", ODD_LINES)
def test_every_line_gives_the_right_event(line: str, event: codec.Event) -> None:
    assert codec.parse_line(line) == event


# Smoothieware answers M114 on the ok line: src/modules/robot/Robot.cpp (print_position: subcode 0
# writes "C: X:%1.4f Y:%1.4f Z:%1.4f" into the gcode's txt_after_ok) and
# src/modules/communication/GcodeDispatch.cpp (prints "ok %s\r\n" with txt_after_ok); an
# extruder appends " E:…" (the example). Marlin prints the position line before its ok.
OK_POSITION_TABLE = [
    ("ok C: X:10.00 Y:20.00 Z:0.00 E:0.00", (10.0, 20.0, 0.0, 0.0)),            # the report
    ("ok C: X:10.0000 Y:20.0000 Z:0.0000", (10.0, 20.0, 0.0, None)),           # Robot.cpp, no extruder
    ("ok C: X:-5.5000 Y:3.2500 Z:12.0000 E:1.2500", (-5.5, 3.25, 12.0, 1.25)),
    ("ok C: X:110.0000 Y:95.0000 Z:5.0000 E:0.0000 ", (110.0, 95.0, 5.0, 0.0)),  # trailing space
]


@pytest.mark.parametrize("line, xyze", OK_POSITION_TABLE)
def test_position_on_the_ok_line(line: str, xyze: tuple) -> None:
    event = codec.parse_line(line)
    assert isinstance(event, codec.Ok)
    assert event.position == codec.Position(*xyze)
    assert event.line is None and not event.advanced and event.temperatures is None


def test_a_plain_ok_carries_no_position() -> None:
    for line in ("ok", "ok N12 P15 B3", "ok T:210.0 /210.0 B:60.0 /60.0"):
        event = codec.parse_line(line)
        assert isinstance(event, codec.Ok) and event.position is None, line
