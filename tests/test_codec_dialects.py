"""The codec on each firmware's answers to what the daemon sends (issue 27, item 1).

One table per dialect: the lines as the firmware prints them, each taken from its source (cited above
the table, function by function) or, where noted, from its documentation or a user's report. Each
line is parsed and compared with the typed event its meaning calls for: the documentation says what a
line means (an acknowledgement, a request for line N, a halt), not the codec.
"""

from __future__ import annotations

from typing import Any

import pytest

from ribbond.printer import codec
from ribbond.printer.codec import ErrorKind

# An expectation: the event's class and the attributes it must have. "temps" maps each heater to
# (current, target, power or None when not reported); "fields" is a subset of M115's fields.
Expect = tuple[type, dict[str, Any]]


def ok(**attrs: Any) -> Expect:
    return codec.Ok, attrs


def error(kind: str, fatal: bool, last_line: int | None = None) -> Expect:
    return codec.Error, {"kind": kind, "fatal": fatal, "last_line": last_line}


def firmware(name: str, **fields: str) -> Expect:
    return codec.FirmwareInfo, {"name": name, "fields": fields}


def position(x: float, y: float, z: float, e: float | None) -> Expect:
    return codec.Position, {"x": x, "y": y, "z": z, "e": e}


def temps(**heaters: tuple[float, float, int | None]) -> Expect:
    return codec.TemperatureReport, {"temps": heaters}


# --------------------------------------------------------------------------------------------- Marlin 2.x
# MarlinFirmware/Marlin (2.1.x):
#   Marlin/src/gcode/queue.cpp: RingBuffer::ok_to_send() ("ok", ADVANCED_OK's " N<line>" " P<planner
#     free>" " B<queue free>"), flush_and_request_resend() (STR_RESEND "Resend: " N, then STR_OK),
#     gcode_line_error() ("Error:" + STR_ERR_LINE_NO / STR_ERR_CHECKSUM_MISMATCH / STR_ERR_NO_CHECKSUM
#     + last_N), get_serial_commands() (STR_WAIT "wait" with NO_TIMEOUTS)
#   Marlin/src/core/language.h: the STR_ERR_* texts, STR_ERR_KILLED "Printer halted. kill() called!",
#     STR_BUSY_PROCESSING "busy: processing" (after "echo:"), STR_UNKNOWN_COMMAND 'Unknown command: "'
#   Marlin/src/module/temperature.cpp: print_heater_state() (" T:%.2f /%.2f", " B:…", " @:", " B@:"),
#     _temp_error() ("Error:" + message + ", system stopped! Heater_ID: " + index or "bed"), the
#     heating waits' " W:" seconds or "?"
#   Marlin/src/gcode/host/M114.cpp report_current_position(), M115.cpp (FIRMWARE_NAME, Cap: lines)
MARLIN2: list[tuple[str, Expect]] = [
    ("ok", ok(line=None, planner_free=None, queue_free=None)),
    ("ok N12 P15 B3", ok(line=12, planner_free=15, queue_free=3)),
    ("ok P15 B3", ok(line=None, planner_free=15, queue_free=3)),
    ("ok T:210.00 /210.00 B:60.00 /60.00 @:127 B@:0",
     ok(temps={"T": (210.0, 210.0, 127), "B": (60.0, 60.0, 0)})),
    (" T:22.05 /0.00 B:21.97 /0.00 @:0 B@:0", temps(T=(22.05, 0.0, 0), B=(21.97, 0.0, 0))),
    (" T:185.40 /210.00 B:59.90 /60.00 @:127 B@:0 W:?", (codec.TemperatureReport, {"waiting": True})),
    ("X:10.00 Y:20.00 Z:0.30 E:1.20 Count X:800 Y:1600 Z:120", position(10.0, 20.0, 0.3, 1.2)),
    ("FIRMWARE_NAME:Marlin 2.1.2.1 (May 25 2023 10:00:00) SOURCE_CODE_URL:github.com/MarlinFirmware/Marlin "
     "PROTOCOL_VERSION:1.0 MACHINE_TYPE:3D Printer KINEMATICS:Cartesian EXTRUDER_COUNT:1 "
     "UUID:cede2a2f-41a2-4748-9b12-c55c62f367ff",
     firmware("Marlin 2.1.2.1 (May 25 2023 10:00:00)", MACHINE_TYPE="3D Printer", KINEMATICS="Cartesian",
              UUID="cede2a2f-41a2-4748-9b12-c55c62f367ff")),
    ("Cap:AUTOREPORT_TEMP:1", (codec.Capability, {"name": "AUTOREPORT_TEMP", "enabled": True})),
    ("Cap:EMERGENCY_PARSER:1", (codec.Capability, {"name": "EMERGENCY_PARSER", "enabled": True})),
    ("echo:busy: processing", (codec.Busy, {"reason": "processing"})),
    ("echo:busy: paused for user", (codec.Busy, {"reason": "paused for user"})),
    ("Resend: 13", (codec.Resend, {"line": 13})),
    ("Error:Line Number is not Last Line Number+1, Last Line: 12", error(ErrorKind.LINE_NUMBER, False, 12)),
    ("Error:checksum mismatch, Last Line: 12", error(ErrorKind.CHECKSUM, False, 12)),
    ("Error:No Checksum with line number, Last Line: 12", error(ErrorKind.NO_CHECKSUM, False, 12)),
    ("Error:Printer halted. kill() called!", error(ErrorKind.HALTED, True)),
    ("Error:Thermal Runaway, system stopped! Heater_ID: 0", error(ErrorKind.THERMAL, True)),
    ("Error:MINTEMP triggered, system stopped! Heater_ID: bed", error(ErrorKind.THERMAL, True)),
    ('echo:Unknown command: "G29"', (codec.UnknownCommand, {"command": "G29"})),
    ("wait", (codec.Wait, {})),
    ("start", (codec.Start, {})),
]

# --------------------------------------------------------------------------------------------- Marlin 1.x
# MarlinFirmware/Marlin (1.1.x): Marlin/Marlin_main.cpp FlushSerialRequestResend() (MSG_RESEND
#   "Resend: " then ok_to_send()), get_serial_commands() (gcode_line_error with MSG_ERR_* and, for a
#   '*' without 'N', MSG_ERR_NO_LINENUMBER_WITH_CHECKSUM), gcode_M105 ("ok" + print_heaterstates()),
#   report_current_position(); Marlin/language.h MSG_M115_REPORT ("FIRMWARE_NAME:Marlin "
#   DETAILED_BUILD_VERSION " SOURCE_CODE_URL:…"), MSG_ERR_STOPPED. The old "Marlin V1; Sprinter/grbl
#   mashup" name is Marlin 1.0's MSG_M115_REPORT, as Creality boards still print it (a user's M115 dump).
MARLIN1: list[tuple[str, Expect]] = [
    ("ok", ok(line=None)),
    ("ok T:20.00 /0.00 B:20.00 /0.00 @:0 B@:0", ok(temps={"T": (20.0, 0.0, 0), "B": (20.0, 0.0, 0)})),
    ("X:0.00 Y:0.00 Z:0.00 E:0.00 Count X:0 Y:0 Z:0", position(0.0, 0.0, 0.0, 0.0)),
    ("FIRMWARE_NAME:Marlin 1.1.9 (Github) SOURCE_CODE_URL:https://github.com/MarlinFirmware/Marlin "
     "PROTOCOL_VERSION:1.0 MACHINE_TYPE:3D Printer EXTRUDER_COUNT:1 UUID:cede2a2f-41a2-4748-9b12-c55c62f367ff",
     firmware("Marlin 1.1.9 (Github)", SOURCE_CODE_URL="https://github.com/MarlinFirmware/Marlin",
              EXTRUDER_COUNT="1")),
    ("FIRMWARE_NAME:Marlin V1; Sprinter/grbl mashup for gen6 FIRMWARE_URL:http://www.mendel-parts.com "
     "PROTOCOL_VERSION:1.0 MACHINE_TYPE:www.creality3d.cn EXTRUDER_COUNT:1 UUID:00000000-0000-0000-0000-000000000000",
     firmware("Marlin V1; Sprinter/grbl mashup for gen6", FIRMWARE_URL="http://www.mendel-parts.com",
              MACHINE_TYPE="www.creality3d.cn")),
    ("Resend: 8", (codec.Resend, {"line": 8})),
    ("Error:No Line Number with checksum, Last Line: 7", error(ErrorKind.NO_LINE_NUMBER, False, 7)),
    ("Error:Heating failed, system stopped! Heater_ID: 0", error(ErrorKind.THERMAL, True)),
    ("Error:Printer stopped due to errors. Fix the error and use M999 to restart. (Temperature is reset. "
     "Set it after restarting)", error(ErrorKind.STOPPED, True)),
    ("echo:busy: processing", (codec.Busy, {"reason": "processing"})),
]

# ------------------------------------------------------------------------------------ Prusa firmware (MK3)
# prusa3d/Prusa-Firmware: Firmware/Marlin_main.cpp: case 105's documentation ("ok T:20.2 /0.0 B:19.1
#   /0.0 T0:20.2 /0.0 @:0 B@:0 P:19.8 A:26.4"; P: the PINDA probe, A: ambient), case 115's
#   documentation (the FIRMWARE_NAME line) and extended_capabilities_report() ("Cap:%S:%c"),
#   gcode_M114() (" Count X: " then stepper positions in mm), FlushSerialRequestResend() ("%S: %ld\n%S\n"
#   with "Resend" and MSG_OK), host_keepalive() (SERIAL_ECHO_START "busy: processing"), kill()
#   (SERIAL_ERROR_START "Printer halted. kill() called!", then the message: MSG_M112_KILL "M112
#   called. Emergency Stop."), the thermal stop (errormagic or, recoverable, echomagic + MSG_ERR_STOPPED);
#   Firmware/cmdqueue.cpp (the line checks' MSG_ERR_* texts); Firmware/messages.cpp.
PRUSA: list[tuple[str, Expect]] = [
    ("ok", ok(line=None)),
    ("ok T:20.2 /0.0 B:19.1 /0.0 T0:20.2 /0.0 @:0 B@:0 P:19.8 A:26.4",
     ok(temps={"T": (20.2, 0.0, 0), "B": (19.1, 0.0, 0), "T0": (20.2, 0.0, None)})),
    ("X:10.00 Y:20.00 Z:0.15 E:0.00 Count X: 10.00 Y:20.00 Z:0.15 E:0.00", position(10.0, 20.0, 0.15, 0.0)),
    ("FIRMWARE_NAME:Prusa-Firmware 3.8.1 based on Marlin FIRMWARE_URL:https://github.com/prusa3d/Prusa-Firmware "
     "PROTOCOL_VERSION:1.0 MACHINE_TYPE:Prusa i3 MK3S EXTRUDER_COUNT:1 UUID:00000000-0000-0000-0000-000000000000",
     firmware("Prusa-Firmware 3.8.1 based on Marlin", MACHINE_TYPE="Prusa i3 MK3S",
              FIRMWARE_URL="https://github.com/prusa3d/Prusa-Firmware")),
    ("Cap:AUTOREPORT_POSITION:1", (codec.Capability, {"name": "AUTOREPORT_POSITION", "enabled": True})),
    ("Resend: 42", (codec.Resend, {"line": 42})),
    ("Error:Line Number is not Last Line Number+1, Last Line: 41", error(ErrorKind.LINE_NUMBER, False, 41)),
    ("Error:checksum mismatch, Last Line: 41", error(ErrorKind.CHECKSUM, False, 41)),
    ("echo:busy: processing", (codec.Busy, {"reason": "processing"})),
    ("echo:busy: paused for input", (codec.Busy, {"reason": "paused for input"})),
    ("Error:Printer halted. kill() called!", error(ErrorKind.HALTED, True)),
    ("M112 called. Emergency Stop.", (codec.Other, {"text": "M112 called. Emergency Stop."})),
    ("Error:Printer stopped due to errors. Supervision required.", error(ErrorKind.STOPPED, True)),
    # recoverable: the firmware pauses and says so as an echo, not as an error
    ("echo:Printer stopped due to errors. Supervision required.",
     (codec.Echo, {"text": "Printer stopped due to errors. Supervision required."})),
    ('echo:Unknown command: "G999"', (codec.UnknownCommand, {"command": "G999"})),
]

# ----------------------------------------------------------------------------------------- RepRapFirmware
# Duet3D/RepRapFirmware (3.x, USB in Marlin compatibility):
#   src/GCodes/GCodes.cpp: HandleReply() (M105: "ok " + reply; a reply and then "ok" otherwise),
#     GenerateTemperatureReport() (the current tool "T:", every tool "T0:", "B:", "%.1f /%.1f"),
#     HandleM114() ("X:%.3f … E:%.3f E0:%.1f Count … Machine … Bed comp …"), DoEmergencyStop()
#     ("Emergency Stop! Reset the controller to continue.")
#   src/GCodes/GCodes2.cpp: case 115 ("FIRMWARE_NAME: %s FIRMWARE_VERSION: %s ELECTRONICS: %s" then
#     " FIRMWARE_DATE: %s"), errorNotSupported ("<command>: Command is not supported")
#   src/Platform/Platform.cpp: "Error: " and "Warning: " before such messages
#   src/GCodes/GCodeBuffer/StringParser.cpp LineFinished(): 3.x drops a line with a bad checksum without
#     a word; 2.05's GCodeBuffer.cpp replaced it with "M998 P<line>", answered "rs " + the line number
#   src/Platform/Event.cpp GetTextDescription(): "Heater %u fault: …", an error; the text as RRF 3
#     prints it in Mellow-3D/FLY-RRF-E3 issue #4.
REPRAPFIRMWARE: list[tuple[str, Expect]] = [
    ("ok", ok(line=None)),
    ("ok T:25.0 /0.0 T0:25.0 /0.0 B:24.9 /0.0",
     ok(temps={"T": (25.0, 0.0, None), "T0": (25.0, 0.0, None), "B": (24.9, 0.0, None)})),
    ("X:10.000 Y:20.000 Z:0.300 E:0.000 E0:0.0 Count 800 1600 1200 Machine 10.000 20.000 0.300 Bed comp 0.000",
     position(10.0, 20.0, 0.3, 0.0)),
    ("FIRMWARE_NAME: RepRapFirmware for Duet 2 WiFi/Ethernet FIRMWARE_VERSION: 3.4.5 ELECTRONICS: Duet WiFi "
     "1.02 or later FIRMWARE_DATE: 2022-11-30 19:35:23",
     firmware("RepRapFirmware for Duet 2 WiFi/Ethernet", FIRMWARE_VERSION="3.4.5",
              ELECTRONICS="Duet WiFi 1.02 or later", FIRMWARE_DATE="2022-11-30 19:35:23")),
    ("rs 42", (codec.Resend, {"line": 42})),
    ("Error: G0/G1: insufficient axes homed", error(ErrorKind.OTHER, False)),
    ("Error: M9999: Command is not supported", error(ErrorKind.OTHER, False)),
    ("Warning: M301: Command is not supported", (codec.Echo, {"text": "M301: Command is not supported"})),
    ("Emergency Stop! Reset the controller to continue.", error(ErrorKind.HALTED, True)),
    ("Error: Heater 0 fault: temperature rising much more slowly than the expected 1.7°C/sec",
     error(ErrorKind.THERMAL, True)),
]

# ------------------------------------------------------------------------------------------- Smoothieware
# Smoothieware/Smoothieware:
#   src/modules/communication/GcodeDispatch.cpp on_console_line_received(): "ok" per command (and to an
#     empty line), "ok %s" with the text modules put after it (M105, M114), "rs N%d" when the checksum
#     or the line number is wrong (no ok), "!!" for every command while halted, "Error: " + text then
#     "Entering Alarm/Halt state", M112's "ok Emergency Stop Requested - reset or M999 required to exit
#     HALT state", M999's "WARNING: After HALT you should HOME as position is currently unknown", an
#     unknown word's "ok - ignored", case 115 (fields separated by ", ")
#   src/modules/tools/temperaturecontrol/TemperatureControl.cpp: M105's "%s:%3.1f /%3.1f @%d " per
#     heater, the heating wait's "%s:%3.1f /%3.1f @%d" each second, "ERROR: …" + "HALT asserted"
#   src/modules/robot/Robot.cpp print_position() ("C: X:%1.4f Y:%1.4f Z:%1.4f"),
#     src/modules/tools/extruder/Extruder.cpp (" E:%1.4f ")
#   src/modules/communication/SerialConsole.cpp on_idle(): Ctrl-X's "HALTED, M999 or $X to exit HALT state"
SMOOTHIEWARE: list[tuple[str, Expect]] = [
    ("ok", ok(line=None, text="")),
    ("ok T:21.0 /0.0 @0 B:21.5 /60.0 @255 ", ok(temps={"T": (21.0, 0.0, 0), "B": (21.5, 60.0, 255)})),
    ("ok C: X:10.0000 Y:20.0000 Z:0.3000 E:1.2500 ", ok(position=codec.Position(10.0, 20.0, 0.3, 1.25))),
    ("T:150.3 /210.0 @255", temps(T=(150.3, 210.0, 255))),
    ("FIRMWARE_NAME:Smoothieware, FIRMWARE_URL:http%3A//smoothieware.org, X-SOURCE_CODE_URL:https://github.com/"
     "Smoothieware/Smoothieware, FIRMWARE_VERSION:edge-bb41e99, PROTOCOL_VERSION:1.0, X-FIRMWARE_BUILD_DATE:Jul "
     "31 2023 15:25:57, X-SYSTEM_CLOCK:100MHz, X-AXES:5, X-GRBL_MODE:0, X-ARCS:1, X-CNC:0, X-MSD:1",
     firmware("Smoothieware", FIRMWARE_URL="http%3A//smoothieware.org", FIRMWARE_VERSION="edge-bb41e99",
              **{"X-SOURCE_CODE_URL": "https://github.com/Smoothieware/Smoothieware", "X-AXES": "5",
                 "X-FIRMWARE_BUILD_DATE": "Jul 31 2023 15:25:57"})),
    ("rs N42", (codec.Resend, {"line": 42})),
    ("!!", error(ErrorKind.HALTED, True)),
    ("ok Emergency Stop Requested - reset or M999 required to exit HALT state", ok(line=None, temperatures=None)),
    ("HALTED, M999 or $X to exit HALT state", error(ErrorKind.HALTED, True)),
    ("Error: unknown", error(ErrorKind.OTHER, False)),
    ("Entering Alarm/Halt state", error(ErrorKind.HALTED, True)),
    ("ERROR: MINTEMP or MAXTEMP triggered on T. Check your temperature sensors!", error(ErrorKind.THERMAL, True)),
    ("HALT asserted - reset or M999 required", error(ErrorKind.HALTED, True)),
    ("ERROR: Temperature runaway on T (delta temp 25.000000), HALT asserted, TURN POWER OFF IMMEDIATELY - "
     "reset or M999 required", error(ErrorKind.THERMAL, True)),
    ("WARNING: After HALT you should HOME as position is currently unknown",
     (codec.Echo, {"text": "After HALT you should HOME as position is currently unknown"})),
    ("ok - ignored", ok(line=None, text="- ignored")),
]

# ----------------------------------------------------------------------------------------------- Repetier
# repetier/Repetier-Firmware (1.0.x, src/ArduinoAVR/Repetier):
#   gcode.cpp: checkAndPushCommand() ("ok " + line number, ACK_WITH_LINENUMBER, printed as the line is
#     queued; "skip N" + "ok" for a line already seen or one of the stale lines after a request;
#     "Error:expected line N got M" then a request; M110's plain "ok"), requestResend() (an empty line,
#     "Resend:" + N, "ok"), readFromSerial() (WAITING_IDENTIFIER "wait" after a second with an empty
#     buffer), keepAlive() ("busy:processing", "busy:heating", "busy:paused for user interaction"),
#     parseAscii() ("Error:" + "Wrong checksum"), reportFatalError() ("fatal:" + message + " - Printer
#     stopped and heaters disabled due to this error. Fix error and restart with M999."),
#     resetFatalError() ("info:Continue from fatal state")
#   Communication.cpp: Com::tFirmware (the FIRMWARE_NAME line), tStart, tInfo "Info:" (HAL.cpp
#     showStartReason: "PowerUp", "External Reset", …), tUnknownCommand
#   Commands.cpp: printTemperatures() ("T:" %.2f " /" target %.0f " B:" … " B@:" … " @:" …),
#     printCurrentPosition() ("X:%.2f Y:%.2f Z:%.3f E:%.4f"), case 115's Com::cap lines
#   Extruder.cpp: fatalError("Heater decoupled during rising"), fatalError("Heater/sensor error")
REPETIER: list[tuple[str, Expect]] = [
    ("ok 12", ok(line=12, planner_free=None, queue_free=None)),
    ("ok", ok(line=None)),
    ("T:20.36 /0 B:20.53 /0 B@:0 @:0", temps(T=(20.36, 0.0, 0), B=(20.53, 0.0, 0))),
    ("X:10.00 Y:20.00 Z:0.300 E:1.2500", position(10.0, 20.0, 0.3, 1.25)),
    ("FIRMWARE_NAME:Repetier_1.0.4 COMPILED:Feb 11 2021 FIRMWARE_URL:https://github.com/repetier/Repetier-Firmware/ "
     "PROTOCOL_VERSION:1.0 MACHINE_TYPE:Mendel EXTRUDER_COUNT:1 REPETIER_PROTOCOL:3",
     firmware("Repetier_1.0.4", COMPILED="Feb 11 2021", MACHINE_TYPE="Mendel", REPETIER_PROTOCOL="3")),
    ("Cap:EMERGENCY_PARSER:1", (codec.Capability, {"name": "EMERGENCY_PARSER", "enabled": True})),
    ("Resend:42", (codec.Resend, {"line": 42})),
    ("skip 43", (codec.Skip, {"line": 43})),
    ("wait", (codec.Wait, {})),
    ("busy:processing", (codec.Busy, {"reason": "processing"})),
    ("busy:heating", (codec.Busy, {"reason": "heating"})),
    ("busy:paused for user interaction", (codec.Busy, {"reason": "paused for user interaction"})),
    ("Error:Wrong checksum", error(ErrorKind.CHECKSUM, False)),
    ("Error:expected line 42 got 44", error(ErrorKind.LINE_NUMBER, False, 41)),
    ("fatal:Heater decoupled during rising - Printer stopped and heaters disabled due to this error. Fix error "
     "and restart with M999.", error(ErrorKind.THERMAL, True)),
    ("fatal:G29 leveling failed! - Printer stopped and heaters disabled due to this error. Fix error and "
     "restart with M999.", error(ErrorKind.STOPPED, True)),
    ("info:Continue from fatal state", (codec.Echo, {"text": "Continue from fatal state"})),
    ("Info:PowerUp", (codec.Echo, {"text": "PowerUp"})),
    ("start", (codec.Start, {})),
    ("Unknown command:G9999", (codec.UnknownCommand, {"command": "G9999"})),
]

TABLES = {"marlin2": MARLIN2, "marlin1": MARLIN1, "prusa": PRUSA, "reprapfirmware": REPRAPFIRMWARE,
          "smoothieware": SMOOTHIEWARE, "repetier": REPETIER}
CASES = [pytest.param(line, expect, id=f"{dialect}: {line[:40]}")
         for dialect, table in TABLES.items() for line, expect in table]


def heaters_of(event: codec.Event) -> dict[str, tuple[float, float | None, int | None]]:
    report = event.temperatures if isinstance(event, (codec.Ok, codec.TemperatureReport)) else None
    assert report is not None, f"{event} carries no temperatures"
    return {h.name: (h.current, h.target, h.power) for h in report.heaters}


def check(event: codec.Event, expect: Expect) -> None:
    kind, attrs = expect
    assert type(event) is kind, f"{event!r} is not a {kind.__name__}"
    for name, value in attrs.items():
        if name == "temps":
            got = heaters_of(event)
            for heater, (current, target, power) in value.items():
                assert heater in got, f"{heater} missing from {got}"
                assert got[heater][:2] == (current, target), (heater, got[heater])
                if power is not None:
                    assert got[heater][2] == power, (heater, got[heater])
        elif name == "fields":
            assert isinstance(event, codec.FirmwareInfo)
            for key, text in value.items():
                assert event.fields.get(key) == text, (key, event.fields)
        else:
            assert getattr(event, name) == value, (name, getattr(event, name), value)


@pytest.mark.parametrize("line, expect", CASES)
def test_each_dialects_answers_parse_to_their_meaning(line: str, expect: Expect) -> None:
    check(codec.parse_line(line), expect)


def test_every_table_covers_what_the_daemon_sends() -> None:
    """Each dialect's table has an acknowledgement, an M105 answer, an M114 answer, M115's name, a
    resend request and an error (every dialect's firmware prints these to what the daemon sends)."""
    needed = {"ok": codec.Ok, "resend": codec.Resend, "firmware": codec.FirmwareInfo, "error": codec.Error}
    for dialect, table in TABLES.items():
        parsed = [codec.parse_line(line) for line, _ in table]
        for what, kind in needed.items():
            assert any(isinstance(e, kind) for e in parsed), f"{dialect}: no {what} line"
        assert any(isinstance(e, codec.TemperatureReport) or isinstance(e, codec.Ok) and e.temperatures
                   for e in parsed), f"{dialect}: no M105 answer"
        assert any(isinstance(e, codec.Position) or isinstance(e, codec.Ok) and e.position
                   for e in parsed), f"{dialect}: no M114 answer"
