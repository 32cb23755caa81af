"""Every fault class is observable from the host side, and reproducible from the seed."""

from __future__ import annotations

import errno
import os
import re
import time

import pytest

from sim import FaultConfig, SimConfig, SimulatedPrinter
from sim.testing import PtyHost, connected, numbered

HALTED = "Error:Printer halted. kill() called!"
TEMP = r" T:\d+\.\d /\d+\.\d B:\d+\.\d /\d+\.\d @:\d+ B@:\d+"


def faulty(**faults: object) -> SimConfig:
    return SimConfig(faults=FaultConfig(**faults))  # type: ignore[arg-type]


def stop_and_wait_host(host: PtyHost, program: list[str], timeout: float = 10.0) -> None:
    """A minimal correct host: one line at a time, honouring Resend, resending on silence."""
    n = 1
    deadline = time.monotonic() + timeout
    while n <= len(program):
        assert time.monotonic() < deadline, "host gave up"
        host.write(numbered(n, program[n - 1]))
        resend = None
        while True:
            line = host.readline(0.2)
            if line is None:  # e.g. a corrupted newline merged it with the next line
                resend = n
                break
            if line.startswith("Resend: "):
                resend = int(line[8:])
            elif line.startswith("ok"):
                if resend is None:
                    n += 1
                break
        if resend is not None:
            host.read_quiet(quiet=0.05)  # the ok that follows a Resend
            n = resend


def test_corruption_caught_and_recovered() -> None:
    program = [f"G1 X{i} Y{2 * i} F3000" for i in range(40)]
    with connected(faulty(corrupt_rate=0.3), ) as (sim, host):
        stop_and_wait_host(host, program)
        st = sim.stats()
        assert st.corrupted_lines > 0
        assert st.checksum_errors + st.line_number_errors > 0
        assert st.resends_requested >= st.checksum_errors + st.line_number_errors
        # Every corrupted numbered line was caught: the program ran exactly once, in order.
        assert [c.command for c in sim.commands()] == program


def _corrupt_run(seed: int) -> list[str]:
    lines = b"".join(numbered(i, f"G1 X{i} F3000") for i in range(1, 31))
    with connected(SimConfig(seed=seed, faults=FaultConfig(corrupt_rate=0.5))) as (sim, host):
        host.write(lines)
        return host.read_quiet()


def test_faults_are_deterministic_from_seed() -> None:
    a, b, c = _corrupt_run(7), _corrupt_run(7), _corrupt_run(8)
    assert a == b
    assert a != c
    assert any(s.startswith("Error:") for s in a)


def test_drop_ok() -> None:
    with connected(faulty(drop_ok_rate=1.0)) as (sim, host):
        host.send("G90", 1)
        host.send("M105")
        assert host.read_quiet(quiet=0.3) == []  # M105's ok line is an ok too
        st = sim.stats()
        assert st.oks_dropped == 2 and st.oks_sent == 0
        assert [c.command for c in sim.commands()] == ["G90", "M105"]


def test_spurious_resend_keeps_receive_buffer() -> None:
    with connected(faulty(spurious_resend_rate=1.0)) as (sim, host):
        host.write(numbered(1, "G90") + numbered(2, "G91"))
        assert host.read_quiet() == ["Resend: 2", "ok", "ok N1 P15 B3",
                                     "Resend: 3", "ok", "ok N2 P15 B3"]
        assert sim.stats().spurious_resends == 2
        assert [c.command for c in sim.commands()] == ["G90", "G91"]  # nothing flushed


def test_unsolicited_lines_interleaved() -> None:
    with connected(faulty(unsolicited_rate=1.0), banner=False) as (sim, host):
        host.read_quiet()  # the banner, itself interleaved
        lines = host.command("G90", 1) + host.command("G90", 2) + host.command("G90", 3)
        assert len(lines) == 6
        extra = lines[0::2]
        assert lines[1::2] == ["ok N1 P15 B3", "ok N2 P15 B3", "ok N3 P15 B3"]
        known = {"echo:busy: processing", "//action:notification Printing...",
                 "echo:Settings Stored (sim)"}
        assert all(s in known or re.fullmatch(TEMP, s) for s in extra), extra
        assert sim.stats().unsolicited_lines >= 3


def test_slow_lines_delayed_in_order() -> None:
    with connected(faulty(slow_rate=1.0, slow_delay_s=0.2), banner=False) as (sim, host):
        host.read_quiet(quiet=0.4)
        t0 = host.write(b"G90\nM105\nG91\n")
        first = host.readline(1.0)
        assert time.monotonic() - t0 >= 0.2
        rest = host.read_quiet()
        assert first == "ok P15 B3"
        assert rest[0].startswith("ok T:") and rest[1] == "ok P15 B3"


def test_reset_after_lines() -> None:
    with connected(faulty(reset_after_lines=3)) as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        assert host.command("G90", 2) == ["ok N2 P15 B3"]
        host.send("G91", 3)  # accepted, then the board reboots: no ok for it
        banner = host.wait_banner()
        assert banner[0] == "start"
        assert host.command("G90", 1) == ["ok N1 P15 B3"]  # line numbers start over
        assert sim.stats().resets == 1


def test_runaway_after_lines() -> None:
    with connected(faulty(runaway_after_lines=2)) as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        host.send("G90", 2)
        assert host.read_quiet() == ["Error:Thermal Runaway, system stopped! Heater_ID: 0", HALTED]
        assert sim.halted_at is not None
        host.send("G90", 3)
        assert host.read_quiet() == [HALTED]


def test_swallow_resent_takes_the_resent_line_silently_then_asks_past_it() -> None:
    """The buggy firmware of issue 22: it asks for line 2 again, takes the re-sent 2 without running
    or answering it, loses 3 with it, and asks for 3 when 4 comes: 2 never ran."""
    with connected(faulty(swallow_resent_after_lines=1)) as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        assert host.command("M117 two", 2) == ["Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok"]
        host.send("M117 two", 2)
        assert host.read_quiet() == [], "the re-sent line is swallowed without a word"
        host.send("M117 three", 3)
        assert host.read_quiet() == [], "and the line after it is lost"
        assert host.command("M117 four", 4) == [
            "Error:Line Number is not Last Line Number+1, Last Line: 2", "Resend: 3", "ok"]
        assert host.command("M117 three", 3) == ["ok N3 P15 B3"]
        assert [(c.line, c.command) for c in sim.commands()] == [(1, "G90"), (3, "M117 three")]
        assert sim.stats().swallowed_line == 2


def test_mintemp_after_lines() -> None:
    """Marlin's MINTEMP error (temperature.cpp _temp_error: "Error:" "MINTEMP triggered"
    ", system stopped! Heater_ID: " 0), then kill()'s line; later lines draw the halted error."""
    with connected(faulty(mintemp_after_lines=2)) as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        host.send("G90", 2)
        assert host.read_quiet() == ["Error:MINTEMP triggered, system stopped! Heater_ID: 0", HALTED]
        assert sim.halted_at is not None
        host.send("G90", 3)
        assert host.read_quiet() == [HALTED]


def _assert_unplugged(host: PtyHost) -> None:
    with pytest.raises(OSError) as info:
        for _ in range(20):
            host.readline(0.1)
    assert info.value.errno == errno.EIO
    with pytest.raises(OSError) as info:
        host.write(b"M105\n")
    assert info.value.errno == errno.EIO


def test_disconnect_after_lines() -> None:
    with connected(faulty(disconnect_after_lines=2)) as (sim, host):
        host.command("G90", 1)
        host.send("G90", 2)
        _assert_unplugged(host)
        assert sim.stats().disconnects == 1
    # Leaving the with-block stopped the simulator cleanly.


def test_triggers_reset_runaway_disconnect_and_reconnect() -> None:
    new_ports: list[str] = []
    cfg = SimConfig(faults=FaultConfig(reconnect_after_s=0.1))
    with SimulatedPrinter(cfg, on_port_change=new_ports.append) as sim:
        with PtyHost(sim.port) as host:
            host.wait_banner()
            host.command("G90", 1)
            sim.trigger_reset()
            host.wait_banner()
            assert host.command("G90", 1) == ["ok N1 P15 B3"]
            sim.trigger_runaway()
            assert host.read_quiet() == [
                "Error:Thermal Runaway, system stopped! Heater_ID: 0", HALTED]
            sim.trigger_disconnect()
            _assert_unplugged(host)
        deadline = time.monotonic() + 2.0
        while not new_ports and time.monotonic() < deadline:
            time.sleep(0.02)
        assert new_ports and sim.port == new_ports[-1] and os.path.exists(sim.port)
        with PtyHost(sim.port) as host:  # plugged back in: a fresh boot
            host.wait_banner()
            assert host.command("M105")[0].startswith("ok T:")


def test_ignore_resent_marks_the_resent_line_received_without_running_or_answering_it() -> None:
    """A firmware that times out after a resend request (issue 36): it asks for line 2 again,
    takes the re-sent 2 as its last line without running or answering it, and runs 3 next."""
    with connected(faulty(ignore_resent_after_lines=1)) as (sim, host):
        assert host.command("G90", 1) == ["ok N1 P15 B3"]
        assert host.command("M117 two", 2) == ["Error:checksum mismatch, Last Line: 1", "Resend: 2", "ok"]
        host.send("M117 two", 2)
        assert host.read_quiet() == [], "the re-sent line draws no answer"
        assert host.command("M117 three", 3) == ["ok N3 P15 B3"], "and the next line is taken as 3"
        assert [(c.line, c.command) for c in sim.commands()] == [(1, "G90"), (3, "M117 three")]
        assert sim.stats().ignored_resent_line == 2


def test_ok_before_output_prints_the_ok_first() -> None:
    config = SimConfig(ok_before_output=True, advanced_ok=False)
    with connected(config) as (sim, host):
        host.send("M114", 1)
        answer = host.read_quiet()
        assert answer[0] == "ok" and answer[1].startswith("X:0.00 Y:0.00 Z:0.00") and len(answer) == 2
