"""The simulator's serial protocol, checked against what Marlin 2.x prints.

Expected values come from Marlin's queue.cpp / gcode handlers, not from earlier runs.
"""

from __future__ import annotations

import re
import time

import pytest
import serial

from sim import FaultConfig, SimConfig
from sim.testing import PtyHost, connected, numbered

TEMP = r"T:\d+\.\d /\d+\.\d B:\d+\.\d /\d+\.\d @:\d+ B@:\d+"
HALTED = "Error:Printer halted. kill() called!"


def fill_queue(host: PtyHost) -> None:
    """Block the queue: M0 waits for the user, three more commands take the other slots."""
    host.write(b"M0\nG90\nG90\nG90\n")
    time.sleep(0.05)


def test_banner_on_open_with_pyserial() -> None:
    with connected(banner=False) as (sim, host):
        host.close()  # a fresh open by pyserial reboots the board and shows the banner
        time.sleep(0.05)
        with serial.Serial(sim.port, 250000, timeout=1.0) as ser:
            lines = []
            while not lines or not lines[-1].startswith("echo:  M203"):
                raw = ser.readline()
                assert raw, f"banner incomplete: {lines}"
                lines.append(raw.decode().rstrip("\n"))
        assert lines[0] == "start"
        assert "echo:Marlin 2.1.2.1" in lines
        assert "echo: Last Updated: 2023-05-25 | Author: (ribbond sim)" in lines
        assert "echo:Compiled: May 25 2023" in lines
        assert any(s.startswith("echo: Free Memory:") and "PlannerBufferBytes:" in s for s in lines)
        assert "echo:Hardcoded Default Settings Loaded" in lines
        assert "echo:  M92 X80.00 Y80.00 Z400.00 E93.00" in lines


def test_advanced_ok_fields() -> None:
    with connected() as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        # A move takes a planner block until it is done; a slow one keeps it.
        assert host.command("G1 X100 F60", 2) == ["ok N2 P14 B3"]
        assert host.command("G91") == ["ok P14 B3"]  # unnumbered: no N field


def test_plain_ok_without_advanced_ok() -> None:
    with connected(SimConfig(advanced_ok=False)) as (sim, host):
        assert host.command("G90", 1) == ["ok"]
        assert host.command("G90") == ["ok"]


def test_line_number_error() -> None:
    with connected() as (sim, host):
        host.write(numbered(2, "G90"))
        assert host.read_quiet() == [
            "Error:Line Number is not Last Line Number+1, Last Line: 0", "Resend: 1", "ok"]
        assert sim.stats().line_number_errors == 1
        assert host.command("G90", 1) == ["ok N1 P15 B3"]


def test_missing_checksum() -> None:
    with connected() as (sim, host):
        host.write(b"N1 G90\n")
        assert host.read_quiet() == [
            "Error:No Checksum with line number, Last Line: 0", "Resend: 1", "ok"]


def test_checksum_without_line_number_is_refused() -> None:
    """The tail of a line cut by a buffer flush has a checksum but no number: never executed."""
    with connected() as (sim, host):
        host.write(b"G1 X10 Y20*45\n")
        assert host.read_quiet() == [
            "Error:No Line Number with checksum, Last Line: 0", "Resend: 1", "ok"]
        assert sim.commands() == []
        host.write(b"G90\n")  # a line with neither number nor checksum is still accepted
        assert host.read_quiet() == ["ok P15 B3"]


def test_marlin2_queues_a_cut_tail_as_an_unnumbered_command() -> None:
    """Marlin 2.x has no "No Line Number with checksum" check: the tail of a cut line is queued
    like any unnumbered command; one that does not parse is answered Unknown command + ok, with no
    resend request (and, with ADVANCED_OK, an ok without N)."""
    with connected(SimConfig(cut_tail="marlin2")) as (sim, host):
        host.write(b"20.25 F3000*45\n")  # cut inside a number: not a command
        assert host.read_quiet() == ['echo:Unknown command: "20.25 F3000"', "ok P15 B3"]
        assert sim.stats().resends_requested == 0 and sim.stats().cut_tails_queued == 1
        assert host.command("G90", 1) == ["ok N1 P15 B3"], "the line numbers are untouched"


def test_skip_refused_asks_for_the_line_after_the_refused_one() -> None:
    """The buggy firmware of the fault: it reports the refusal of line 1 with its last accepted
    line (0), yet asks for 2, and line 1 never runs."""
    with connected(SimConfig(faults=FaultConfig(skip_refused=True))) as (sim, host):
        host.write(b"N1 G90*0\n")
        assert host.read_quiet() == ["Error:checksum mismatch, Last Line: 0", "Resend: 2", "ok"]
        assert host.command("G91", 2) == ["ok N2 P15 B3"]
        assert [c.line for c in sim.commands()] == [2]
        assert sim.stats().skipped_lines == 1


def test_no_ok_after_resend_when_disabled() -> None:
    with connected(SimConfig(ok_after_resend=False)) as (sim, host):
        host.write(b"N1 G90*0\n")
        assert host.read_quiet() == ["Error:checksum mismatch, Last Line: 0", "Resend: 1"]


def test_checksum_error_flushes_receive_buffer() -> None:
    """The bad line's error discards every byte already in the receive buffer."""
    with connected() as (sim, host):
        fill_queue(host)
        bad = b"N1 G90*0\n"  # the checksum of "N1 G90" is not 0
        host.write(bad + numbered(2, "G91") + numbered(3, "G91"))
        time.sleep(0.05)  # they wait in the receive buffer: the queue is full
        host.write(b"M108\n")  # the emergency parser releases M0 at once
        assert host.read_quiet() == [
            "ok P15 B0",  # M0, its slot still counted
            "Error:checksum mismatch, Last Line: 0",
            "Resend: 1",
            "ok",
            "ok P15 B1", "ok P15 B2", "ok P15 B3",  # the three queued G90
        ]
        # N2, N3 and the M108 line were in the buffer when it was flushed.
        assert [c.command for c in sim.commands()] == ["M0", "G90", "G90", "G90"]
        st = sim.stats()
        assert st.checksum_errors == 1 and st.resends_requested == 1
        assert host.command("G91", 1) == ["ok N1 P15 B3"]


def test_m110_sets_line_number() -> None:
    with connected() as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        # The number taken is the N after M110; the line's own N is only echoed.
        assert host.command("M110 N0", 5) == ["ok N5 P15 B3"]
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        assert host.command("M110 N100", 2) == ["ok N2 P15 B3"]
        assert host.command("G90", 101) == ["ok N101 P15 B3"]
        assert sim.stats().line_number_errors == 0


def test_m105_never_has_advanced_ok_fields() -> None:
    with connected() as (sim, host):
        lines = host.command("M105", 1)
        assert len(lines) == 1
        assert re.fullmatch("ok " + TEMP, lines[0]), lines
        assert lines[0] == "ok T:25.0 /0.0 B:25.0 /0.0 @:0 B@:0"


def test_m115_capabilities() -> None:
    with connected() as (sim, host):
        lines = host.command("M115", 1)
        assert lines[0].startswith("FIRMWARE_NAME:Marlin 2.1.2.1 (sim) ")
        for field in ("SOURCE_CODE_URL:github.com/MarlinFirmware/Marlin", "PROTOCOL_VERSION:1.0",
                      "MACHINE_TYPE:ribbond-sim", "KINEMATICS:Cartesian", "EXTRUDER_COUNT:1",
                      "UUID:"):
            assert field in lines[0]
        caps = dict(s[4:].rsplit(":", 1) for s in lines[1:-1])
        assert all(s.startswith("Cap:") for s in lines[1:-1])
        required = {"SERIAL_XON_XOFF": "0", "BINARY_FILE_TRANSFER": "0", "EEPROM": "0",
                    "AUTOREPORT_TEMP": "1", "AUTOREPORT_POS": "0", "PROGRESS": "0",
                    "PRINT_JOB": "1", "AUTOLEVEL": "0", "EMERGENCY_PARSER": "1",
                    "HOST_ACTION_COMMANDS": "1", "PROMPT_SUPPORT": "0",
                    "THERMAL_PROTECTION": "1", "ARCS": "0"}
        assert {k: caps.get(k) for k in required} == required
        assert "ADVANCED_OK" not in caps  # hosts learn it from the ok format
        assert lines[-1] == "ok N1 P15 B3"


def test_autoreport_temperatures() -> None:
    with connected() as (sim, host):
        assert host.command("M155 S0.1") == ["ok P15 B3"]
        t0 = time.monotonic()
        lines = host.read_quiet(quiet=0.3, timeout=0.55)
        reports = [s for s in lines if re.fullmatch(" " + TEMP, s)]
        assert len(reports) >= 3, lines
        assert time.monotonic() - t0 < 1.0
        host.command("M155 S0")
        time.sleep(0.05)
        host.read_quiet(quiet=0.05)
        assert host.read_quiet(quiet=0.4) == []


@pytest.mark.timing
def test_m109_waits_with_temperature_and_busy_lines() -> None:
    # tau 15 s physical, 25 -> 199 °C: 15 * ln(175) = 77 s physical, 1.55 s wall at 0.02.
    with connected(SimConfig(time_scale=0.02, keepalive_s=0.3)) as (sim, host):
        t0 = host.send("M109 S200", 1)
        lines = host.read_until(lambda s: s.startswith("ok"), timeout=5.0)
        elapsed = time.monotonic() - t0
        assert 1.3 < elapsed < 2.2, elapsed
        waits = [s for s in lines if re.fullmatch(" " + TEMP + " W:\\?", s)]
        assert len(waits) >= 2, lines  # one at once, then every second
        assert lines.count("echo:busy: processing") >= 3, lines
        assert lines[-1] == "ok N1 P15 B3"
        report = host.command("M105")[0]
        assert float(re.search(r"T:([\d.]+)", report).group(1)) >= 199.0


def test_m109_released_by_m108() -> None:
    with connected(SimConfig(time_scale=1.0)) as (sim, host):
        host.send("M109 S200")
        time.sleep(0.2)
        assert host.read_quiet(quiet=0.05)[0].endswith("W:?")
        host.send("M108")
        lines = host.read_quiet()
        # The M108 line itself was queued behind M109, hence B2 on M109's ok.
        assert [s for s in lines if s.startswith("ok")] == ["ok P15 B2", "ok P15 B3"]


def test_the_queue_holds_the_running_command_and_those_behind_it() -> None:
    """Marlin keeps a command in its ring buffer until it is done: M0 heads it while it waits."""
    with connected() as (sim, host):
        host.send("M0", 1)
        host.send("G91", 2)
        host.send("G90")
        time.sleep(0.1)
        assert sim.queued() == ["M0", "G91", "G90"]
        host.send("M108")
        host.read_quiet()
        assert sim.queued() == []


def test_temperature_limits_refused() -> None:
    with connected() as (sim, host):
        lines = host.command("M104 S300")
        assert lines[0].startswith("echo:") and lines[-1] == "ok P15 B3"
        assert host.command("M105")[0].startswith("ok T:25.0 /0.0 ")
        host.command("M140 S60")
        assert " B:25.0 /60.0 " in host.command("M105")[0]


def test_m0_waits_until_m108() -> None:
    with connected(SimConfig(keepalive_s=0.1)) as (sim, host):
        host.send("M0", 1)
        lines = host.read_for(0.35)
        assert "echo:busy: paused for user" in lines
        assert not any(s.startswith("ok") for s in lines)
        host.send("M108")
        assert host.read_quiet() == ["ok N1 P15 B2", "ok P15 B3"]


def test_unknown_command_is_acknowledged_and_recorded() -> None:
    with connected() as (sim, host):
        assert host.command("G29 P1", 1) == ['echo:Unknown command: "G29 P1"', "ok N1 P15 B3"]
        assert host.command("hello") == ['echo:Unknown command: "hello"', "ok P15 B3"]
        assert [(c.line, c.command) for c in sim.commands()] == [(1, "G29 P1"), (None, "hello")]


def test_comments_and_blank_lines_ignored() -> None:
    with connected() as (sim, host):
        host.write(b"\n   \n; just a comment\n  G90 ; absolute\n")
        assert host.read_quiet() == ["ok P15 B3"]
        assert [c.command for c in sim.commands()] == ["G90"]


def test_flood_beyond_receive_buffer_is_lost() -> None:
    with connected(SimConfig(rx_buffer=128)) as (sim, host):
        fill_queue(host)
        flood = b"".join(f"G1 X{i} Y{i}\n".encode() for i in range(100))
        host.write(flood)
        time.sleep(len(flood) * 10 / 250000 + 0.05)
        st = sim.stats()
        assert st.rx_peak == 128
        assert st.dropped_bytes == len(flood) - 128
        host.write(b"M108\n")  # lost as well, yet the emergency parser still sees it
        lines = host.read_quiet()
        assert lines[0] == "ok P15 B0"
        assert sim.stats().dropped_bytes == len(flood) + 5 - 128


def test_m112_halts_fast_with_full_queue_and_buffer() -> None:
    with connected() as (sim, host):
        fill_queue(host)
        host.write(b"".join(f"G1 X{i} Y{i} F3000\n".encode() for i in range(20)))
        time.sleep(0.05)
        assert sim.stats().dropped_bytes > 0  # the receive buffer is full
        t0 = host.write(b"M112\n")
        line = host.readline(timeout=1.0)
        t1 = time.monotonic()
        assert line == HALTED
        assert t1 - t0 < 0.05
        assert sim.halted_at is not None and sim.halted_at - t0 < 0.05
        assert host.read_quiet(quiet=0.1) == []  # nothing queued survives
        # Halted: every line is answered with the error and no ok.
        host.send("M105")
        host.send("G90", 1)
        assert host.read_quiet() == [HALTED, HALTED]
        # M999 acts as a reset: banner, line numbers from 0 again.
        host.send("M999")
        host.wait_banner()
        assert sim.halted_at is None
        assert host.command("G90", 1) == ["ok N1 P15 B3"]


def test_m410_quickstop_empties_planner() -> None:
    with connected(SimConfig(time_scale=1.0)) as (sim, host):
        for i in range(1, 6):
            host.command(f"G1 X{10 * i} F600", i)  # 1 s each
        time.sleep(0.3)
        host.write(b"M410\n")
        assert host.read_quiet() == ["ok P15 B3"]
        x = float(re.search(r"Count X:(-?\d+)", host.command("M114")[0]).group(1)) / 80
        assert 1.0 < x < 6.0  # stopped about 0.3 s into the first 10 mm at 10 mm/s


def test_m114_reports_position() -> None:
    with connected() as (sim, host):
        host.command("G1 X12.5 Y7 Z0.3 F60000")
        host.command("M400")
        assert host.command("M114") == [
            "X:12.50 Y:7.00 Z:0.30 E:0.00 Count X:1000 Y:560 Z:120", "ok P15 B3"]
        host.command("G92 X0 E5")
        assert host.command("M114")[0].startswith("X:0.00 Y:7.00 Z:0.30 E:5.00 ")


def test_g28_homes_in_three_physical_seconds() -> None:
    with connected(SimConfig(time_scale=0.05)) as (sim, host):
        host.command("G1 X20 Y30 Z5 F60000")
        t0 = host.send("G28")
        assert host.readline(2.0) == "ok P15 B3"
        assert 0.15 <= time.monotonic() - t0 < 0.22  # 3 s physical at 0.05
        assert host.command("M114")[0].startswith("X:0.00 Y:0.00 Z:0.00 ")
        host.command("G1 X20 Y30 Z5")
        host.command("G28 X")
        assert host.command("M114")[0].startswith("X:0.00 Y:30.00 Z:5.00 ")


def test_other_known_commands_just_ok() -> None:
    with connected() as (sim, host):
        for command in ("M106 S128", "M107", "M84", "M999", "M17", "M117 hello", "T0"):
            assert host.command(command) == ["ok P15 B3"], command
        assert host.command("M118 E1 hi there") == ["echo:hi there", "ok P15 B3"]


def test_wait_idle() -> None:
    with connected(SimConfig(time_scale=0.01)) as (sim, host):
        host.write("G1 X50 F3000\nG1 X0\n")  # 2 x 1 s physical = 20 ms wall
        assert sim.wait_idle(2.0)
        host.write("M0\n")
        assert not sim.wait_idle(0.2)
        host.write("M108\n")
        assert sim.wait_idle(2.0)
