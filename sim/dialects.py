"""How each firmware family answers on the serial line: the simulator's ``--dialect NAME``.

A :class:`Dialect` holds the answers (banner, ``M115``, ``M105``/``M114`` formats, ``ok`` forms,
busy lines, resend requests, errors) and the defaults of the options that differ (ADVANCED_OK, an
``ok`` after a resend request, ``M114`` on the ``ok`` line, the cut-tail check, keepalive). Each
format is written from the firmware's own source, cited beside it; ``firmware.py`` decides *when*
each is printed. No dialect (``None``) is the simulator's historical board: Marlin 2.1's answers
with ADVANCED_OK on and Marlin 1.x's stricter cut-tail check.

The simulator imports nothing from ribbond: these tables are written from the firmware sources, not
from ribbond's codec, so a misreading cannot hide in both.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Dialect", "DIALECTS", "STOCK", "dialect_named"]

MACHINE_UUID = "cede2a2f-41a2-4748-9b12-c55c62f367ff"  # Marlin's default MACHINE_UUID

_MARLIN_CAPS = (
    ("SERIAL_XON_XOFF", 0), ("BINARY_FILE_TRANSFER", 0), ("EEPROM", 0),
    ("VOLUMETRIC", 0), ("AUTOREPORT_POS", 0), ("AUTOREPORT_TEMP", 1),
    ("PROGRESS", 0), ("PRINT_JOB", 1), ("AUTOLEVEL", 0), ("RUNOUT", 0),
    ("Z_PROBE", 0), ("LEVELING_DATA", 0), ("BUILD_PERCENT", 0),
    ("SOFTWARE_POWER", 0), ("TOGGLE_LIGHTS", 0), ("CASE_LIGHT_BRIGHTNESS", 0),
    ("EMERGENCY_PARSER", 1), ("HOST_ACTION_COMMANDS", 1), ("PROMPT_SUPPORT", 0),
    ("SDCARD", 0), ("AUTOREPORT_SD_STATUS", 0), ("LONG_FILENAME", 0),
    ("THERMAL_PROTECTION", 1), ("MOTION_MODES", 0), ("ARCS", 0),
    ("BABYSTEPPING", 0), ("CHAMBER_TEMPERATURE", 0), ("MEATPACK", 0),
    ("CONFIG_EXPORT", 0),
)
# Marlin 1.1.x Marlin_main.cpp gcode_M115 (EXTENDED_CAPABILITIES_REPORT)
_MARLIN1_CAPS = (("EEPROM", 0), ("AUTOREPORT_TEMP", 1), ("PROGRESS", 0), ("PRINT_JOB", 1),
                 ("AUTOLEVEL", 0), ("Z_PROBE", 0), ("LEVELING_DATA", 0), ("SOFTWARE_POWER", 0),
                 ("TOGGLE_LIGHTS", 0), ("CASE_LIGHT_BRIGHTNESS", 0), ("EMERGENCY_PARSER", 1))
# Prusa-Firmware Marlin_main.cpp extended_capabilities_report(), cap_line("%S:%c")
_PRUSA_CAPS = (("AUTOREPORT_TEMP", 1), ("AUTOREPORT_FANS", 1), ("AUTOREPORT_POSITION", 1),
               ("EXTENDED_M20", 1), ("PRUSA_MMU2", 1))
# Repetier-Firmware Commands.cpp case 115 (Com::cap), the default Configuration.h
_REPETIER_CAPS = (("PROGRESS", 0), ("AUTOREPORT_TEMP", 1), ("HOST_RESCUE", 0), ("EEPROM", 1),
                  ("AUTOLEVEL", 0), ("Z_PROBE", 0), ("SOFTWARE_POWER", 0), ("TOGGLE_LIGHTS", 0),
                  ("PAUSESTOP", 1), ("PREHEAT", 1), ("EMERGENCY_PARSER", 1))

MARLIN_SETTINGS = ("echo:; Steps per unit:", "echo:  M92 X80.00 Y80.00 Z400.00 E93.00",
                    "echo:; Maximum feedrates (units/s):", "echo:  M203 X300.00 Y300.00 Z5.00 E25.00")


@dataclass(frozen=True)
class Dialect:
    """One firmware family's answers (formats use ``str.format`` fields named in each comment)."""

    name: str
    #: Lines after a (re)boot; the first is ``start`` where the firmware prints one
    #: (``{planner_bytes}``: the planner's size in bytes, as Marlin prints it).
    banner: tuple[str, ...]
    #: ``M115``'s report: the ``FIRMWARE_NAME`` line, then ``Cap:`` lines.
    m115: tuple[str, ...]
    # ---- defaults of SimConfig options
    advanced_ok: bool
    ok_after_resend: bool
    m114_on_ok: bool
    cut_tail: str
    keepalive_s: float
    # ---- protocol behaviour
    #: Line checks: "marlin" (queue.cpp), "smoothie" (rs N, no flush), "repetier" (skip, flush),
    #: "rrf" (a bad checksum drops the line silently; numbers not checked).
    line_checks: str
    #: The ``ok`` is printed when the line is received (Repetier), not once it is processed.
    ok_on_receipt: bool
    #: ``ok`` carries the line number: ``ok 12`` (Repetier's ACK_WITH_LINENUMBER).
    ok_numbered: bool
    #: Answers an empty line with ``ok`` (Smoothieware).
    answers_empty_line: bool
    #: Prints ``wait`` after a second with an empty command buffer (Repetier).
    says_wait: bool
    #: Has ``M155`` temperature autoreports (Marlin, Prusa, Repetier; not RepRapFirmware's USB
    #: Marlin mode nor Smoothieware, which answer it as an unknown command).
    m155: bool
    #: ``M108``/``M112``/``M410`` are acted on as they arrive (Marlin's EMERGENCY_PARSER).
    emergency_parser: bool
    #: Opening the port reboots the board (a USB-serial chip's DTR); native USB boards do not.
    resets_on_open: bool
    #: What the halt (``M112``, a heater error) leaves: "halt" (until M999), "reboot" (the board
    #: restarts: Prusa's kill(), Repetier's KILL_METHOD 1).
    halt: str
    #: ``{n}``: the line asked for again.
    resend: str
    #: ``{reason}``: "processing", "paused for user", "heating".
    busy: str
    #: ``{command}``: an unknown command's text ("" prints nothing: Smoothieware answers ``ok``).
    unknown: str
    #: Printed for every command while halted ("" ignores it).
    halted_answer: str
    #: Lines of an emergency stop (``M112``), of a thermal runaway and of a broken thermistor.
    stop_lines: tuple[str, ...]
    runaway_lines: tuple[str, ...]
    mintemp_lines: tuple[str, ...]
    #: Command buffer slots (Marlin BUFSIZE 4; Repetier GCODE_BUFFER_SIZE 1).
    bufsize: int = 4


def _marlin_temps(h: tuple[float, float, int], b: tuple[float, float, int], digits: int = 2) -> str:
    # Marlin 2.x temperature.cpp print_heater_state(): " T:%.2f /%.2f", then " @:" and " B@:" powers
    return (f"T:{h[0]:.{digits}f} /{h[1]:.{digits}f} B:{b[0]:.{digits}f} /{b[1]:.{digits}f} "
            f"@:{h[2]} B@:{b[2]}")


def temperature_report(dialect: Dialect | None, h: tuple[float, float, int], b: tuple[float, float, int]) -> str:
    """The temperature report of ``M105``/``M155`` without ``ok``; ``h``, ``b``: current, target, power."""
    name = dialect.name if dialect is not None else None
    if name == "prusa":
        # Prusa Marlin_main.cpp M105's documentation: "ok T:20.2 /0.0 B:19.1 /0.0 T0:20.2 /0.0 @:0 B@:0
        # P:19.8 A:26.4" (P: the PINDA probe, A: ambient; the simulator has neither: 25.0)
        return (f"T:{h[0]:.1f} /{h[1]:.1f} B:{b[0]:.1f} /{b[1]:.1f} T0:{h[0]:.1f} /{h[1]:.1f} "
                f"@:{h[2]} B@:{b[2]} P:25.0 A:25.0")
    if name == "reprapfirmware":
        # GCodes.cpp GenerateTemperatureReport(): the current tool "T:", each tool "T0:", "B:" (%.1f /%.1f)
        return f"T:{h[0]:.1f} /{h[1]:.1f} T0:{h[0]:.1f} /{h[1]:.1f} B:{b[0]:.1f} /{b[1]:.1f}"
    if name == "smoothieware":
        # TemperatureControl.cpp on_gcode_received(): "%s:%3.1f /%3.1f @%d " per heater
        return f"T:{h[0]:.1f} /{h[1]:.1f} @{h[2]} B:{b[0]:.1f} /{b[1]:.1f} @{b[2]} "
    if name == "repetier":
        # Commands.cpp printTemperatures(): "T:" temp (2 digits) " /" target (0 digits), " B:", " B@:", " @:"
        return f"T:{h[0]:.2f} /{h[1]:.0f} B:{b[0]:.2f} /{b[1]:.0f} B@:{b[2]} @:{h[2]}"
    if name in ("marlin1", "marlin2"):
        return _marlin_temps(h, b)
    return _marlin_temps(h, b, digits=1)  # the historical board


def position_report(dialect: Dialect | None, pos: tuple[float, float, float, float],
                    counts: tuple[int, int, int]) -> str:
    """``M114``'s report (its own line; Smoothieware's is the text after ``ok``)."""
    x, y, z, e = pos
    name = dialect.name if dialect is not None else None
    if name == "prusa":
        # Prusa Marlin_main.cpp gcode_M114(): the stepper positions in mm after " Count X: "
        return f"X:{x:.2f} Y:{y:.2f} Z:{z:.2f} E:{e:.2f} Count X: {x:.2f} Y:{y:.2f} Z:{z:.2f} E:{e:.2f}"
    if name == "reprapfirmware":
        # GCodes.cpp HandleM114(): axes "%.3f", "E:", "E0:%.1f", "Count", "Machine", "Bed comp"
        return (f"X:{x:.3f} Y:{y:.3f} Z:{z:.3f} E:{e:.3f} E0:{e:.1f} Count {counts[0]} {counts[1]} "
                f"{counts[2]} Machine {x:.3f} {y:.3f} {z:.3f} Bed comp 0.000")
    if name == "smoothieware":
        # Robot.cpp print_position(): "C: X:%1.4f Y:%1.4f Z:%1.4f"; Extruder.cpp appends " E:%1.4f "
        return f"C: X:{x:.4f} Y:{y:.4f} Z:{z:.4f} E:{e:.4f}"
    if name == "repetier":
        # Commands.cpp printCurrentPosition(): X, Y with 2 digits, Z with 3, E with 4
        return f"X:{x:.2f} Y:{y:.2f} Z:{z:.3f} E:{e:.4f}"
    # Marlin: report_current_position(): "X:%.2f Y:%.2f Z:%.2f E:%.2f" then " Count X:… Y:… Z:…"
    return f"X:{x:.2f} Y:{y:.2f} Z:{z:.2f} E:{e:.2f} Count X:{counts[0]} Y:{counts[1]} Z:{counts[2]}"


_KILLED = "Error:Printer halted. kill() called!"
_MARLIN_RUNAWAY = ("Error:Thermal Runaway, system stopped! Heater_ID: 0", _KILLED)
# temperature.cpp _temp_error(): "Error:" + STR_T_MINTEMP + STR_STOPPED_HEATER + the heater's index
_MARLIN_MINTEMP = ("Error:MINTEMP triggered, system stopped! Heater_ID: 0", _KILLED)
_REPETIER_FATAL = ("fatal:{} - Printer stopped and heaters disabled due to this error. Fix error and "
                   "restart with M999.")  # gcode.cpp reportFatalError()


def _marlin(name: str, version: str, caps: tuple[tuple[str, int], ...], cut_tail: str,
            advanced_ok: bool) -> Dialect:
    m115 = (f"FIRMWARE_NAME:Marlin {version} SOURCE_CODE_URL:github.com/MarlinFirmware/Marlin "
            f"PROTOCOL_VERSION:1.0 MACHINE_TYPE:ribbond-sim KINEMATICS:Cartesian EXTRUDER_COUNT:1 "
            f"UUID:{MACHINE_UUID}")
    short = version.split()[0]
    return Dialect(
        name=name,
        banner=("start", f"echo:Marlin {short}", "echo: Last Updated: 2023-05-25 | Author: (ribbond sim)",
                "echo:Compiled: May 25 2023", "echo: Free Memory: 4086  PlannerBufferBytes: {planner_bytes}",
                "echo:Hardcoded Default Settings Loaded", *MARLIN_SETTINGS),
        m115=(m115, *(f"Cap:{cap}:{value}" for cap, value in caps)),
        advanced_ok=advanced_ok, ok_after_resend=True, m114_on_ok=False, cut_tail=cut_tail, keepalive_s=2.0,
        line_checks="marlin", ok_on_receipt=False, ok_numbered=False, answers_empty_line=False,
        says_wait=False, m155=True, emergency_parser=True, resets_on_open=True, halt="halt",
        resend="Resend: {n}", busy="echo:busy: {reason}", unknown='echo:Unknown command: "{command}"',
        halted_answer=_KILLED, stop_lines=(_KILLED,), runaway_lines=_MARLIN_RUNAWAY,
        mintemp_lines=_MARLIN_MINTEMP)


#: The historical board (no --dialect): Marlin 2.1.2.1's answers, ADVANCED_OK on, 1.x's cut-tail check.
STOCK = _marlin("stock", "2.1.2.1 (sim)", _MARLIN_CAPS, cut_tail="reject", advanced_ok=True)

DIALECTS: dict[str, Dialect] = {d.name: d for d in (
    # Marlin 1.1.9: Configuration_adv.h leaves ADVANCED_OK off; get_serial_commands() refuses a
    # checksum without a line number ("No Line Number with checksum").
    _marlin("marlin1", "1.1.9 (Github)", _MARLIN1_CAPS, cut_tail="reject", advanced_ok=False),
    # Marlin 2.1: ADVANCED_OK off by default; queue.cpp has no check for '*' without 'N'.
    _marlin("marlin2", "2.1.2.1 (May 25 2023 10:00:00)", _MARLIN_CAPS, cut_tail="marlin2", advanced_ok=False),
    Dialect(
        name="prusa",
        # Marlin_main.cpp setup(): "start", then echo lines
        banner=("start", "echo: 3.13.2-7080", "echo:Hardcoded Default Settings Loaded", *MARLIN_SETTINGS),
        # Marlin_main.cpp case 115 (its doc comment shows the line), then extended_capabilities_report()
        m115=("FIRMWARE_NAME:Prusa-Firmware 3.13.2+7080_c6e8fa0 based on Marlin "
              "FIRMWARE_URL:https://github.com/prusa3d/Prusa-Firmware PROTOCOL_VERSION:1.0 "
              "MACHINE_TYPE:Prusa i3 MK3S EXTRUDER_COUNT:1 UUID:00000000-0000-0000-0000-000000000000",
              *(f"Cap:{cap}:{value}" for cap, value in _PRUSA_CAPS)),
        advanced_ok=False, ok_after_resend=True, m114_on_ok=False, cut_tail="reject", keepalive_s=2.0,
        line_checks="marlin", ok_on_receipt=False, ok_numbered=False, answers_empty_line=False,
        says_wait=False, m155=True, emergency_parser=False, resets_on_open=True, halt="reboot",
        # FlushSerialRequestResend(): "%S: %ld\n%S\n" with "Resend" and MSG_OK
        resend="Resend: {n}", busy="echo:busy: {reason}", unknown='echo:Unknown command: "{command}"',
        halted_answer=_KILLED,
        # kill(): SERIAL_ERROR_START "Printer halted. kill() called!", then the message (MSG_M112_KILL)
        stop_lines=(_KILLED, "M112 called. Emergency Stop."),
        runaway_lines=_MARLIN_RUNAWAY, mintemp_lines=_MARLIN_MINTEMP),
    Dialect(
        name="reprapfirmware",
        banner=(),  # native USB: nothing on the port at boot
        # GCodes2.cpp case 115: "FIRMWARE_NAME: %s FIRMWARE_VERSION: %s ELECTRONICS: %s" " FIRMWARE_DATE: %s"
        m115=("FIRMWARE_NAME: RepRapFirmware for Duet 2 WiFi/Ethernet FIRMWARE_VERSION: 3.5.3 "
              "ELECTRONICS: Duet WiFi 1.02 or later FIRMWARE_DATE: 2024-09-18 10:54:22",),
        advanced_ok=False, ok_after_resend=False, m114_on_ok=False, cut_tail="marlin2", keepalive_s=0.0,
        line_checks="rrf", ok_on_receipt=False, ok_numbered=False, answers_empty_line=False,
        says_wait=False, m155=False, emergency_parser=False, resets_on_open=False, halt="halt",
        resend="", busy="", unknown="Error: {command}: Command is not supported",  # GCodes2.cpp
        halted_answer="",
        stop_lines=("Emergency Stop! Reset the controller to continue.",),  # GCodes.cpp DoEmergencyStop()
        # Event.cpp GetTextDescription(): "Heater %u fault: %s%s", an error message; the text as
        # RepRapFirmware 3 prints it (Mellow-3D/FLY-RRF-E3 issue #4). RRF turns the heater off and
        # pauses a print from its own card; the simulator halts, as a host's stream must stop too.
        runaway_lines=("Error: Heater 1 fault: temperature rising much more slowly than the expected 2.1°C/sec",),
        mintemp_lines=("Error: Heater 1 fault: sensor open circuit",)),
    Dialect(
        name="smoothieware",
        banner=(),  # native USB: "Smoothie Running @100MHz" is printed at power up, not on opening the port
        # GcodeDispatch.cpp case 115
        m115=("FIRMWARE_NAME:Smoothieware, FIRMWARE_URL:http%3A//smoothieware.org, "
              "X-SOURCE_CODE_URL:https://github.com/Smoothieware/Smoothieware, FIRMWARE_VERSION:edge-bb41e99, "
              "PROTOCOL_VERSION:1.0, X-FIRMWARE_BUILD_DATE:Jul 31 2023 15:25:57, X-SYSTEM_CLOCK:100MHz, "
              "X-AXES:5, X-GRBL_MODE:0, X-ARCS:1, X-CNC:0, X-MSD:1",),
        advanced_ok=False, ok_after_resend=False, m114_on_ok=True, cut_tail="marlin2", keepalive_s=0.0,
        line_checks="smoothie", ok_on_receipt=False, ok_numbered=False, answers_empty_line=True,
        says_wait=False, m155=False, emergency_parser=False, resets_on_open=False, halt="halt",
        resend="rs N{n}", busy="", unknown="", halted_answer="!!",
        stop_lines=("ok Emergency Stop Requested - reset or M999 required to exit HALT state",),
        # TemperatureControl.cpp on_second_tick() and sensor checks
        runaway_lines=("ERROR: Temperature runaway on T (delta temp 25.000000), HALT asserted, TURN POWER "
                       "OFF IMMEDIATELY - reset or M999 required",),
        mintemp_lines=("ERROR: MINTEMP or MAXTEMP triggered on T. Check your temperature sensors!",
                       "HALT asserted - reset or M999 required")),
    Dialect(
        name="repetier",
        # Printer.cpp setup(): Com::tStart, HAL::showStartReason() ("Info:" + reason), free RAM
        banner=("start", "Info:External Reset", "Free RAM:3250"),
        # Communication.cpp Com::tFirmware, then Commands.cpp case 115's Com::cap lines
        m115=("FIRMWARE_NAME:Repetier_1.0.4 COMPILED:Aug  3 2022 FIRMWARE_URL:https://github.com/repetier/"
              "Repetier-Firmware/ PROTOCOL_VERSION:1.0 MACHINE_TYPE:Mendel EXTRUDER_COUNT:1 REPETIER_PROTOCOL:3",
              *(f"Cap:{cap}:{value}" for cap, value in _REPETIER_CAPS)),
        advanced_ok=False, ok_after_resend=True, m114_on_ok=False, cut_tail="marlin2",
        keepalive_s=2.0,  # Configuration.h KEEP_ALIVE_INTERVAL 2000
        line_checks="repetier", ok_on_receipt=True, ok_numbered=True, answers_empty_line=False,
        says_wait=True, m155=True, emergency_parser=True, resets_on_open=True, halt="reboot",
        resend="Resend:{n}", busy="busy:{reason}", unknown="Unknown command:{command}",
        halted_answer=_REPETIER_FATAL.format("Heater decoupled during hold"),
        stop_lines=(),  # KILL_METHOD 1: Commands::emergencyStop() resets the board at once
        runaway_lines=(_REPETIER_FATAL.format("Heater decoupled during hold"),),
        mintemp_lines=(_REPETIER_FATAL.format("Heater/sensor error"),),
        bufsize=1),  # Repetier.h GCODE_BUFFER_SIZE 1: the next line is read once this one has run
)}

#: Repetier's keepalive words for the busy states (gcode.cpp keepAlive()).
REPETIER_BUSY = {"processing": "processing", "paused for user": "paused for user interaction",
                 "heating": "heating"}


def dialect_named(name: str | None) -> Dialect | None:
    """The dialect called ``name`` (None: the historical board); ValueError names the choices."""
    if name is None:
        return None
    try:
        return DIALECTS[name]
    except KeyError:
        raise ValueError(f"dialect must be one of {', '.join(DIALECTS)}, got {name!r}") from None
