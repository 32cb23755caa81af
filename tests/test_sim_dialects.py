"""The simulator's dialects (``--dialect``) answer as each firmware's source says it does.

The expected forms are written here from the firmwares' sources (the same ones cited in
``sim/dialects.py`` and ``tests/test_codec_dialects.py``) as regular expressions on the raw lines,
not through ribbond's codec: the simulator stands in for firmware by others.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from sim.__main__ import build_parser, config_from_args
from sim.config import SimConfig
from sim.testing import PtyHost, connected, numbered

NUM = r"-?\d+\.\d+"
#: Per dialect: the M115 name line, the M105 answer, the M114 answer (position 10, 20, 0.3, 0).
FORMS = {
    # Marlin 2.x: M115.cpp; print_heater_states() "T:%.2f /%.2f … @: B@:"; report_current_position()
    "marlin2": (r"FIRMWARE_NAME:Marlin 2\.\S+ .*SOURCE_CODE_URL:\S+ PROTOCOL_VERSION:1\.0 .*UUID:\S+$",
                rf"^ok T:{NUM} /{NUM} B:{NUM} /{NUM} @:\d+ B@:\d+$",
                r"^X:10\.00 Y:20\.00 Z:0\.30 E:0\.00 Count X:800 Y:1600 Z:120$"),
    "marlin1": (r"FIRMWARE_NAME:Marlin 1\.1\.\d+ \(Github\) SOURCE_CODE_URL:",
                rf"^ok T:{NUM} /{NUM} B:{NUM} /{NUM} @:\d+ B@:\d+$",
                r"^X:10\.00 Y:20\.00 Z:0\.30 E:0\.00 Count X:800 Y:1600 Z:120$"),
    # Prusa Marlin_main.cpp: case 105's and case 115's documentation, gcode_M114()
    "prusa": (r"^FIRMWARE_NAME:Prusa-Firmware 3\.\S+ based on Marlin FIRMWARE_URL:https://github\.com/prusa3d/"
              r"Prusa-Firmware PROTOCOL_VERSION:1\.0 MACHINE_TYPE:Prusa i3 MK3S EXTRUDER_COUNT:1 UUID:\S+$",
              r"^ok T:\d+\.\d /\d+\.\d B:\d+\.\d /\d+\.\d T0:\d+\.\d /\d+\.\d @:\d+ B@:\d+ P:\d+\.\d A:\d+\.\d$",
              r"^X:10\.00 Y:20\.00 Z:0\.30 E:0\.00 Count X: 10\.00 Y:20\.00 Z:0\.30 E:0\.00$"),
    # RRF GCodes2.cpp case 115; GCodes.cpp GenerateTemperatureReport(), HandleM114()
    "reprapfirmware": (r"^FIRMWARE_NAME: RepRapFirmware for Duet .* FIRMWARE_VERSION: 3\.\S+ ELECTRONICS: .* "
                       r"FIRMWARE_DATE: \d{4}-\d\d-\d\d \d\d:\d\d:\d\d$",
                       r"^ok T:\d+\.\d /\d+\.\d T0:\d+\.\d /\d+\.\d B:\d+\.\d /\d+\.\d$",
                       r"^X:10\.000 Y:20\.000 Z:0\.300 E:0\.000 E0:0\.0 Count 800 1600 120 "
                       r"Machine 10\.000 20\.000 0\.300 Bed comp 0\.000$"),
    # Smoothieware GcodeDispatch.cpp case 115; TemperatureControl.cpp "%s:%3.1f /%3.1f @%d "; Robot.cpp
    "smoothieware": (r"^FIRMWARE_NAME:Smoothieware, FIRMWARE_URL:http%3A//smoothieware\.org, "
                     r"X-SOURCE_CODE_URL:https://github\.com/Smoothieware/Smoothieware, FIRMWARE_VERSION:\S+, "
                     r"PROTOCOL_VERSION:1\.0, ",
                     r"^ok T:\d+\.\d /\d+\.\d @\d+ B:\d+\.\d /\d+\.\d @\d+ $",
                     r"^ok C: X:10\.0000 Y:20\.0000 Z:0\.3000 E:0\.0000"),
    # Repetier Communication.cpp Com::tFirmware; Commands.cpp printTemperatures(), printCurrentPosition()
    "repetier": (r"^FIRMWARE_NAME:Repetier_1\.0\.\d+ COMPILED:.* FIRMWARE_URL:https://github\.com/repetier/"
                 r"Repetier-Firmware/ PROTOCOL_VERSION:1\.0 MACHINE_TYPE:\S+ EXTRUDER_COUNT:1 REPETIER_PROTOCOL:3$",
                 r"^T:\d+\.\d\d /\d+ B:\d+\.\d\d /\d+ B@:\d+ @:\d+$",
                 r"^X:10\.00 Y:20\.00 Z:0\.300 E:0\.0000$"),
}


@contextmanager
def board(dialect: str, **options: object) -> Iterator[PtyHost]:
    options.setdefault("time_scale", 0.001)
    with connected(SimConfig(dialect=dialect, **options), banner=False) as (_, host):  # type: ignore[arg-type]
        yield host


def lines_until(host: PtyHost, pattern: str, timeout: float = 2.0) -> list[str]:
    return host.read_until(lambda s: re.search(pattern, s) is not None, timeout)


@pytest.mark.parametrize("dialect", list(FORMS))
def test_m115_m105_and_m114_answers(dialect: str) -> None:
    name, temperatures, pos = FORMS[dialect]
    with board(dialect) as host:
        host.read_quiet(0.2)                                         # a banner, where there is one
        host.send("M110 N0", 0)
        lines_until(host, r"^ok")
        host.send("M115", 1)
        assert re.search(name, lines_until(host, name)[-1])
        host.read_quiet(0.1)
        host.send("M105", 2)
        assert re.search(temperatures, lines_until(host, temperatures)[-1])
        host.read_quiet(0.1)
        host.send("G1 X10 Y20 Z0.3 F6000", 3)
        host.send("M400", 4)
        host.send("M114", 5)
        got = lines_until(host, pos)
        assert not any(line.startswith(("Error", "!!", "rs", "Resend")) for line in got), got


def test_ok_forms_and_when_they_come() -> None:
    """Marlin acknowledges a dwell once it is done; Repetier on receipt, with the line number
    (gcode.cpp checkAndPushCommand: "ok " + actLineNumber right after queueing)."""
    with board("marlin2", time_scale=0.05) as marlin:
        marlin.read_quiet(0.2)
        sent = marlin.send("G4 S4", 1)                            # 0.2 s of wall time
        lines_until(marlin, r"^ok$")
        assert time.monotonic() - sent >= 0.19
    with board("repetier", time_scale=0.05) as repetier:
        repetier.read_quiet(0.2)
        sent = repetier.send("G4 S4", 1)
        lines_until(repetier, r"^ok 1$")
        assert time.monotonic() - sent < 0.15, "acknowledged on receipt"


def test_repetier_busy_and_wait() -> None:
    """keepAlive(): "busy:processing" while a command blocks; readFromSerial(): "wait" once the
    buffer has been empty for a second."""
    with board("repetier", time_scale=1.0, keepalive_s=0.2) as host:
        host.read_quiet(0.2)
        host.send("G4 P600", 1)
        got = host.read_for(0.55)
        assert "ok 1" in got and "busy:processing" in got, got
        assert "wait" not in got
        later = host.read_for(1.3)
        assert "wait" in later, later


@pytest.mark.parametrize("dialect, answer", [
    # queue.cpp gcode_line_error(): the error with the last line, flush, "Resend: " N, "ok"
    ("marlin2", ["Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok"]),
    ("prusa", ["Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok"]),
    # GcodeDispatch.cpp: "rs N%d" and no ok
    ("smoothieware", ["rs N2"]),
    # gcode.cpp: parseAscii's "Error:Wrong checksum", requestResend(): empty line, "Resend:" N, "ok"
    ("repetier", ["Error:Wrong checksum", "", "Resend:2", "ok"]),
    # StringParser.cpp LineFinished(): dropped without a word
    ("reprapfirmware", []),
])
def test_a_bad_checksum_is_answered_in_each_dialects_words(dialect: str, answer: list[str]) -> None:
    with board(dialect) as host:
        host.read_quiet(0.2)
        host.send("M110 N0", 0)
        host.send("G1 X1 F3000", 1)
        host.read_quiet(0.2)
        bad = numbered(2, "G1 X2 F3000").replace(b"G1 X2", b"G1 X3")      # the checksum of another line
        host.write(bad)
        assert host.read_quiet(0.25) == answer


def test_repetier_skips_stale_lines_after_asking_again() -> None:
    """A line out of order: "Error:expected line N got M" and a request; the stale line sent again
    is skipped (waitingForResend), and so is a line it already has."""
    with board("repetier") as host:
        host.read_quiet(0.2)
        host.send("M110 N0", 0)
        host.send("G1 X1 F3000", 1)
        assert host.read_quiet(0.2)[-1] == "ok 1"
        host.send("G1 X3 F3000", 3)
        assert host.read_quiet(0.2) == ["Error:expected line 2 got 3", "", "Resend:2", "ok"]
        host.send("G1 X3 F3000", 3)
        assert host.read_quiet(0.2) == ["skip 3", "ok"]
        host.send("G1 X1 F3000", 1)
        assert host.read_quiet(0.2) == ["skip 1", "ok"]
        host.send("G1 X2 F3000", 2)
        assert host.read_quiet(0.2) == ["ok 2"]


def test_smoothieware_answers_an_empty_line_and_halts_as_it_does() -> None:
    """GcodeDispatch.cpp: "ok" to an empty line; M112's "ok Emergency Stop Requested …"; then "!!"
    for a move, queries still answered, M999's warning and ok. SerialConsole.cpp: Ctrl-X halts
    at once ("HALTED, M999 or $X to exit HALT state")."""
    with board("smoothieware") as host:
        host.write(b"\n")
        assert host.read_quiet(0.2) == ["ok"]
        host.send("M112")
        assert host.read_quiet(0.2) == ["ok Emergency Stop Requested - reset or M999 required to exit HALT state"]
        host.send("G1 X5")
        assert host.read_quiet(0.2) == ["!!"]
        host.send("M105")
        assert host.read_quiet(0.2)[0].startswith("ok T:")
        host.send("M999")
        assert host.read_quiet(0.2) == ["WARNING: After HALT you should HOME as position is currently unknown", "ok"]
        host.write(b"\x18")
        assert host.read_quiet(0.2) == ["HALTED, M999 or $X to exit HALT state"]


@pytest.mark.parametrize("dialect, lines, reboots", [
    ("marlin2", ["Error:Printer halted. kill() called!"], False),            # kill()
    ("prusa", ["Error:Printer halted. kill() called!", "M112 called. Emergency Stop."], True),  # kill(), softReset()
    ("reprapfirmware", ["Emergency Stop! Reset the controller to continue."], False),  # DoEmergencyStop()
    ("repetier", [], True),                                                   # KILL_METHOD 1: reset
])
def test_the_emergency_stop_in_each_dialect(dialect: str, lines: list[str], reboots: bool) -> None:
    with board(dialect) as host:
        host.read_quiet(0.2)
        host.send("M112")
        got = host.read_quiet(0.3)
        assert got[:len(lines)] == lines
        assert ("start" in got[len(lines):]) == reboots, got


def test_unknown_commands_in_each_dialects_words() -> None:
    expected = {"marlin2": 'echo:Unknown command: "G999"',              # gcode.cpp unknown_command_warning
                "reprapfirmware": "Error: G999: Command is not supported",  # GCodes2.cpp errorNotSupported
                "repetier": "Unknown command:G999"}                         # Commands.cpp tUnknownCommand
    for dialect, line in expected.items():
        with board(dialect) as host:
            host.read_quiet(0.2)
            host.send("G999")
            assert line in host.read_quiet(0.2), dialect
    with board("smoothieware") as host:                                     # dispatched to no module: ok
        host.send("G999")
        assert host.read_quiet(0.2) == ["ok"]


def test_a_dialects_options_are_defaults_an_explicit_option_overrides() -> None:
    smoothie = SimConfig(dialect="smoothieware")
    assert (smoothie.m114_on_ok, smoothie.ok_after_resend, smoothie.advanced_ok) == (True, False, False)
    assert SimConfig(dialect="smoothieware", ok_after_resend=True).ok_after_resend is True
    assert SimConfig(dialect="repetier").bufsize == 1                      # Repetier.h GCODE_BUFFER_SIZE
    stock = SimConfig()
    assert (stock.advanced_ok, stock.cut_tail, stock.bufsize) == (True, "reject", 4)   # as before
    args = build_parser().parse_args(["--dialect", "marlin2", "--advanced-ok", "--no-ok-after-resend"])
    config = config_from_args(args)
    assert (config.dialect, config.advanced_ok, config.ok_after_resend, config.cut_tail) == (
        "marlin2", True, False, "marlin2")
    with pytest.raises(ValueError, match="dialect must be one of marlin1, marlin2, prusa"):
        SimConfig(dialect="grbl")
