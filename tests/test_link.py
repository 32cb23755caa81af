"""The printer link against the simulated Marlin printer, over the simulator's pty."""

from __future__ import annotations

import asyncio
import logging
import os
import re
import select
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path

import pytest

from ribbond.printer import (
    Capabilities,
    Disconnected,
    LinkState,
    NotReady,
    PrinterHalted,
    PrinterLink,
    PrinterReset,
    PrinterSilent,
    ProtocolError,
    StreamCancelled,
    Timeouts,
    prepare_program,
)
from sim import FaultConfig

from .conftest import HOST_COMMANDS, assert_prefix_without_duplicates, executed_program, moves

FAST = Timeouts(default_s=0.5, probes=4)


def link_for(sim, **kwargs) -> PrinterLink:
    """A link to ``sim``, told the window of its board (128-byte buffer unless the test says)."""
    kwargs.setdefault("timeouts", FAST)
    kwargs.setdefault("capabilities", Capabilities(rx_buffer_bytes=sim.config.rx_buffer - 1))
    kwargs.setdefault("boot_wait_s", 1.0)
    return PrinterLink(sim.port, sim.config.baud, **kwargs)


async def test_handshake_learns_the_firmware(make_sim) -> None:
    sim = make_sim()
    link = link_for(sim)
    await link.connect()
    status = link.status
    assert status.state is LinkState.READY
    assert status.firmware.startswith("Marlin")
    assert status.capabilities["AUTOREPORT_TEMP"] and status.capabilities["EMERGENCY_PARSER"]
    assert "ADVANCED_OK" not in status.capabilities
    assert status.advanced_ok, "learned from the acknowledgements"
    assert [c.command for c in sim.commands()][:2] == ["M110 N0", "M115"]
    await link.close()


async def test_plain_ok_firmware_is_detected(make_sim) -> None:
    sim = make_sim(advanced_ok=False)
    link = link_for(sim)
    await link.connect()
    assert not link.status.advanced_ok
    await link.close()


async def test_send_and_queries(make_sim) -> None:
    sim = make_sim()
    link = link_for(sim)
    await link.connect()
    await link.send("M104 S200")
    temps = await link.query_temperatures()
    assert temps.hotend is not None and temps.hotend.target == 200.0
    await link.send("G28")
    await link.send("G1 X12.5 Y7 Z3 F6000")
    position = await link.query_position()
    assert (position.x, position.y, position.z) == (12.5, 7.0, 3.0)
    answer = await link.send("G999")
    assert any(getattr(e, "command", None) == "G999" for e in answer.events)
    await link.close()


@pytest.mark.parametrize("advanced_ok", [True, False], ids=["advanced-ok", "plain-ok"])
async def test_a_position_on_the_ok_line_is_taken(make_sim, advanced_ok: bool) -> None:
    """Smoothieware answers M114 with ``ok C: X:… Y:… Z:… E:…`` (no position line before it, no
    N/P/B fields): the position is taken from the ok, the ok acknowledges the M114 (not a line
    after it), and the capabilities learn at connect where the firmware puts it."""
    sim = make_sim(m114_on_ok=True, advanced_ok=advanced_ok)
    link = link_for(sim)
    await link.connect()
    assert link.capabilities.position_report == "ok", "learned at connect from an M114's answer"
    await link.send("G28")
    await link.send("G1 X12.5 Y7 Z3 F6000")
    position = await asyncio.wait_for(link.query_position(grace_s=0.0), 5)
    assert (position.x, position.y, position.z, position.e) == (12.5, 7.0, 3.0, 0.0)
    assert link.status.position == (12.5, 7.0, 3.0, 0.0)
    assert link.capabilities.position_report == "ok"
    # the acknowledgements stay in step: the next command's answer is its own
    await link.send("G1 X-4.25 Y30 F6000")
    again = await link.query_position(grace_s=0.0)
    assert (again.x, again.y) == (-4.25, 30.0)
    temps = await link.query_temperatures()
    assert temps.hotend is not None
    program = [*moves(300)[:150], "M114", *moves(300)[150:]]
    before = len(sim.commands())
    await link.stream(program)
    assert [c.command for c in sim.commands()[before:]] == program
    await link.close()


@pytest.mark.parametrize("ping_pong", [False, True], ids=["windowed", "ping-pong"])
async def test_clean_stream_executes_every_line_once_in_order(make_sim, ping_pong: bool) -> None:
    sim = make_sim()
    link = link_for(sim, ping_pong=ping_pong)
    await link.connect()
    program = moves(500)
    seen: list[int] = []
    result = await link.stream(program, lambda p: seen.append(p.acknowledged))
    assert result.lines == 500 and result.resends == 0
    assert executed_program(sim) == program
    assert seen[-1] == 500 and seen == sorted(seen)
    assert sim.stats().dropped_bytes == 0, "the window never overruns the receive buffer"
    await link.close()


FAULTS = {
    "corrupted-bytes": FaultConfig(corrupt_rate=0.05),
    "lost-oks": FaultConfig(drop_ok_rate=0.05),
    "spurious-resends": FaultConfig(spurious_resend_rate=0.03),
    "unsolicited-lines": FaultConfig(unsolicited_rate=0.2),
    "slow-answers": FaultConfig(slow_rate=0.05, slow_delay_s=0.05),
}


@pytest.mark.parametrize("advanced_ok", [True, False], ids=["advanced-ok", "plain-ok"])
@pytest.mark.parametrize("fault", list(FAULTS))
async def test_each_fault_alone_still_executes_every_line_once_in_order(make_sim, fault: str, advanced_ok: bool) -> None:
    sim = make_sim(faults=FAULTS[fault], advanced_ok=advanced_ok, seed=7)
    link = link_for(sim)
    await link.connect()
    program = moves(800, seed=3)
    await link.stream(program)
    assert executed_program(sim) == program
    stats = sim.stats()
    if fault == "corrupted-bytes":
        assert stats.checksum_errors + stats.line_number_errors > 0, "the fault must have happened"
    if fault == "lost-oks":
        assert stats.oks_dropped > 0
    await link.close()


@pytest.mark.parametrize("advanced_ok", [True, False], ids=["advanced-ok", "plain-ok"])
async def test_marlin2_cut_tails_are_not_taken_for_acknowledgements(make_sim, advanced_ok: bool) -> None:
    """Marlin 2.x answers the tail of a line cut by its flush as an unnumbered command
    (``echo:Unknown command`` + ``ok``): that ok must not acknowledge the line asked for again,
    or the printer's next request for it would end the stream with a false "printer reset"."""
    # A main loop 0.2 ms late to its receive buffer: the flush after an error cuts the line then
    # arriving (20 bytes at 1 Mbaud).
    sim = make_sim(faults=FaultConfig(corrupt_rate=0.05), cut_tail="marlin2", advanced_ok=advanced_ok,
                   read_latency_s=0.0002, seed=5)
    link = link_for(sim)
    await link.connect()
    program = moves(3500, seed=4)
    await link.stream(program)
    # Every numbered line ran once, in order. (A tail that happens to parse, e.g. cut right after
    # its "N<k>", runs unnumbered as well: Marlin 2.x's own hazard, not the host's to prevent.)
    numbered = [c.command for c in sim.commands() if c.line is not None
                and c.command.split()[0] not in HOST_COMMANDS]
    assert numbered == program
    assert sim.stats().cut_tails_queued > 0, "the flushes must have cut lines"
    await link.close()


async def test_a_printer_that_skips_a_refused_line_stops_the_stream(make_sim) -> None:
    """A printer that marks a refused line received and asks for the next one would run the job
    with that line missing: the stream stops, names the line, and what ran is exactly the lines
    before it."""
    sim = make_sim(faults=FaultConfig(corrupt_rate=0.02, skip_refused=True), seed=3)
    link = link_for(sim)
    await link.connect()
    program = moves(3500, seed=4)
    with pytest.raises(ProtocolError, match=r"after refusing line \d+ \(program line \d+:") as caught:
        await link.stream(program)
    assert sim.stats().skipped_lines >= 1
    message = str(caught.value)
    refused = int(re.search(r"after refusing line (\d+)", message).group(1))
    index = int(re.search(r"program line (\d+)", message).group(1)) - 1
    assert refused not in [c.line for c in sim.commands()], "the refused line never ran"
    executed = executed_program(sim)
    assert executed[:index] == program[:index], "everything before it ran, once, in order"
    await link.close()


async def test_a_printer_that_swallows_a_resent_line_stops_the_stream(make_sim) -> None:
    """Issue 22: the printer asks for line N again, takes the re-sent N without running or answering
    it and later asks for N + 1. The stream stops naming N (it is not counted as done), N never
    ran, everything before it ran once in order, and the link numbers lines again: it is usable."""
    sim = make_sim(faults=FaultConfig(swallow_resent_after_lines=300))
    link = link_for(sim)
    await link.connect()
    program = moves(1500, seed=4)
    with pytest.raises(ProtocolError, match=r"never line (\d+) \(program line (\d+): ") as caught:
        await link.stream(program)
    swallowed = sim.stats().swallowed_line
    message = str(caught.value)
    assert re.search(r"never line (\d+)", message).group(1) == str(swallowed)
    index = int(re.search(r"program line (\d+)", message).group(1)) - 1
    assert program[index] in message
    assert swallowed not in [c.line for c in sim.commands()], "the swallowed line never ran"
    executed = executed_program(sim)
    assert executed[:index] == program[:index], "everything before it ran, once, in order"
    assert program[index] not in executed, "the line named is the one that did not run"
    assert link.state is LinkState.READY
    await link.send("M400")                     # the link works again: the safe stop can go out
    await link.close()


async def test_without_ok_after_resend(make_sim) -> None:
    sim = make_sim(faults=FaultConfig(corrupt_rate=0.05), ok_after_resend=False, seed=11)
    link = link_for(sim, capabilities=Capabilities(ok_after_resend=False))
    await link.connect()
    program = moves(600, seed=5)
    await link.stream(program)
    assert executed_program(sim) == program
    await link.close()


async def test_fifty_thousand_lines_under_all_faults_at_once(make_sim) -> None:
    faults = FaultConfig(corrupt_rate=0.003, drop_ok_rate=0.003, spurious_resend_rate=0.002,
                         unsolicited_rate=0.02, slow_rate=0.002, slow_delay_s=0.02)
    # A 32-bit board: a deeper queue and receive buffer keep more lines in flight, so more of them
    # are caught by each error, flush and resend.
    sim = make_sim(faults=faults, baud=2_000_000, time_scale=1e-5, bufsize=8, rx_buffer=256, seed=2026)
    link = link_for(sim, capabilities=Capabilities(rx_buffer_bytes=255))
    await link.connect()
    program = moves(50_000, seed=9)
    result = await link.stream(program)
    assert executed_program(sim) == program
    stats = sim.stats()
    assert stats.checksum_errors + stats.line_number_errors > 0 and stats.oks_dropped > 0
    assert stats.spurious_resends > 0 and stats.unsolicited_lines > 0 and stats.slow_lines > 0
    assert result.resends > 0
    await link.close()


async def test_reset_mid_job_fails_clearly_without_duplicates(make_sim) -> None:
    sim = make_sim(faults=FaultConfig(reset_after_lines=300))
    link = link_for(sim)
    await link.connect()
    program = moves(2000)
    with pytest.raises(PrinterReset, match="reset"):
        await link.stream(program)
    assert_prefix_without_duplicates(executed_program(sim), program)
    await link.wait_for_state(LinkState.READY, timeout=5)  # it shakes hands again afterwards
    await link.close()


async def test_disconnect_mid_job_fails_clearly_without_duplicates(make_sim) -> None:
    sim = make_sim(faults=FaultConfig(disconnect_after_lines=300))
    link = link_for(sim)
    await link.connect()
    program = moves(2000)
    with pytest.raises(Disconnected, match="disconnected|closed"):
        await link.stream(program)
    assert link.state is LinkState.DISCONNECTED
    assert_prefix_without_duplicates(executed_program(sim), program)


async def test_an_unplugged_port_is_one_error_line_without_a_traceback(make_sim, caplog) -> None:
    """A vanished port is the workshop's event, not a bug: one ERROR record naming the port and
    what to do, no traceback at WARNING or above."""
    sim = make_sim(faults=FaultConfig(disconnect_after_lines=300))
    link = link_for(sim)
    port = sim.port
    await link.connect()
    caplog.set_level("DEBUG", logger="ribbond.printer")
    with pytest.raises(Disconnected, match=rf"printer disconnected: {re.escape(port)}: "):
        await link.stream(moves(2000))
    loud = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert [r.levelname for r in loud] == ["ERROR"], [r.getMessage() for r in loud]
    message = loud[0].getMessage()
    assert message.startswith(f"printer disconnected: {port}: ") and "reconnect" in message, message
    assert loud[0].exc_info is None


async def test_thermal_runaway_halts_the_stream(make_sim) -> None:
    sim = make_sim(faults=FaultConfig(runaway_after_lines=200))
    link = link_for(sim)
    await link.connect()
    with pytest.raises(PrinterHalted, match="Thermal Runaway"):
        await link.stream(moves(2000))
    assert link.state is LinkState.HALTED
    await link.close()


async def test_a_mintemp_error_halts_the_stream_and_the_link(make_sim) -> None:
    """MINTEMP (a thermistor unplugged or broken) is fatal: the stream stops with the printer's
    own words (the MINTEMP line halts the link, not only kill()'s line after it), the link is
    halted, and what ran is the program's beginning."""
    sim = make_sim(faults=FaultConfig(mintemp_after_lines=200))
    link = link_for(sim)
    await link.connect()
    program = moves(2000)
    with pytest.raises(PrinterHalted, match="MINTEMP triggered, system stopped! Heater_ID: 0"):
        await link.stream(program)
    assert link.state is LinkState.HALTED
    assert_prefix_without_duplicates(executed_program(sim), program)
    assert len(executed_program(sim)) < 200
    await link.close()


async def test_emergency_stop_halts_within_100ms_with_a_full_queue(make_sim) -> None:
    # Real time and slow moves: the planner and the command queue fill up and stay full.
    sim = make_sim(baud=250000, time_scale=1.0)
    link = link_for(sim)
    await link.connect()
    program = [f"G1 X{10 + (i % 2) * 50} Y10 F600" for i in range(200)]
    streaming = asyncio.ensure_future(link.stream(program))
    await asyncio.sleep(0.5)
    assert sim.stats().planner_peak >= 15, "the planner must be full for this test to mean something"
    called = time.monotonic()
    link.emergency_stop()
    with pytest.raises(PrinterHalted):
        await asyncio.wait_for(streaming, 2)
    deadline = time.monotonic() + 1
    while sim.halted_at is None and time.monotonic() < deadline:
        await asyncio.sleep(0.005)
    assert sim.halted_at is not None
    assert sim.halted_at - called < 0.1
    assert link.state is LinkState.HALTED
    await link.close()


class ScriptedPrinter:
    """A pty whose 'firmware' is a function: ``answer(index, line)`` gives the bytes to reply to
    the index-th line received. For printers the simulator does not play: a board that does not
    reset on open and is still halted, firmware that crashed behind a live USB bridge."""

    def __init__(self, answer: Callable[[int, bytes], bytes]) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.port = os.ttyname(slave)
        os.close(slave)
        self._answer = answer
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        pending = b""
        index = 0
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            try:
                pending += os.read(self.master, 4096)
            except OSError:
                continue  # no host has the port open (yet)
            while b"\n" in pending:
                line, pending = pending.split(b"\n", 1)
                reply = self._answer(index, line)
                index += 1
                if reply:
                    os.write(self.master, reply)

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        os.close(self.master)


async def test_silent_printer_is_reported_not_waited_on() -> None:
    # It acknowledges the handshake (M110, M115) and then never answers again.
    printer = ScriptedPrinter(lambda index, line: b"ok\n" if index < 2 else b"")
    try:
        link = PrinterLink(printer.port, 250000, timeouts=Timeouts(default_s=0.3, probes=2), boot_wait_s=0.2)
        await link.connect()
        started = time.monotonic()
        with pytest.raises(PrinterSilent, match="no answer"):
            await link.stream(moves(100))
        assert time.monotonic() - started < 3
        await link.close()
    finally:
        printer.close()


async def test_pause_resume_and_cancel(make_sim) -> None:
    sim = make_sim(time_scale=0.01)
    link = link_for(sim)
    await link.connect()
    program = moves(3000)
    streaming = asyncio.ensure_future(link.stream(program))
    await asyncio.sleep(0.2)
    link.pause()
    assert link.state is LinkState.PAUSED
    await asyncio.sleep(0.3)
    count = len(executed_program(sim))
    await asyncio.sleep(0.3)
    assert len(executed_program(sim)) == count, "nothing new is fed while paused"
    link.resume()
    await asyncio.sleep(0.2)
    assert len(executed_program(sim)) > count
    link.cancel()
    with pytest.raises(StreamCancelled):
        await streaming
    assert link.state is LinkState.READY
    executed = executed_program(sim)
    assert 0 < len(executed) < len(program)
    assert_prefix_without_duplicates(executed, program)
    await link.close()


def test_prepare_program_names_the_bad_line() -> None:
    good = prepare_program(["; header", "", "N10 G28*18", "G1 X1 ; move", "  "], source="a.gcode")
    assert good == ["G28", "G1 X1"]
    with pytest.raises(ValueError, match=r"b\.gcode, line 3: .*characters"):
        prepare_program(["G28", "G1 X1", "M117 " + "x" * 120], source="b.gcode")
    with pytest.raises(ValueError, match="line 2: M110"):
        prepare_program(["G28", "M110 N0"])


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.printer", *args], capture_output=True, text=True, timeout=120)


def test_stream_command_exits_zero_when_every_line_was_acknowledged(make_sim, tmp_path: Path) -> None:
    sim = make_sim(faults=FaultConfig(corrupt_rate=0.02), seed=5)
    program = moves(400)
    path = tmp_path / "part.gcode"
    path.write_text("; a part\n" + "\n".join(program) + "\n")
    done = run_cli("stream", "--port", sim.port, "--baud", str(sim.config.baud), "--boot-wait", "1", "-q", str(path))
    assert done.returncode == 0, done.stderr
    assert "400 lines acknowledged" in done.stdout
    assert executed_program(sim) == program


def test_stream_command_fails_with_the_reason(make_sim, tmp_path: Path) -> None:
    sim = make_sim(faults=FaultConfig(runaway_after_lines=100))
    path = tmp_path / "part.gcode"
    path.write_text("\n".join(moves(1000)) + "\n")
    done = run_cli("stream", "--port", sim.port, "--baud", str(sim.config.baud), "--boot-wait", "1", "-q", str(path))
    assert done.returncode == 1
    assert "Thermal Runaway" in done.stderr


def test_stream_command_rejects_a_bad_file_before_connecting(tmp_path: Path) -> None:
    path = tmp_path / "bad.gcode"
    path.write_text("G28\nM117 " + "x" * 200 + "\n")
    done = run_cli("stream", "--port", "/dev/does-not-exist", str(path))
    assert done.returncode == 2
    assert "bad.gcode, line 2" in done.stderr
    missing = run_cli("stream", "--port", "/dev/does-not-exist", str(tmp_path / "nope.gcode"))
    assert missing.returncode == 2


def test_stream_command_reports_a_missing_port(tmp_path: Path) -> None:
    path = tmp_path / "ok.gcode"
    path.write_text("G28\n")
    done = run_cli("stream", "--port", "/dev/does-not-exist", str(path))
    assert done.returncode == 1
    assert "/dev/does-not-exist" in done.stderr


async def test_connecting_to_a_halted_printer_says_so() -> None:
    # A board that does not reset on open, still halted from an earlier emergency stop.
    printer = ScriptedPrinter(lambda index, line: b"Error:Printer halted. kill() called!\n")
    try:
        link = PrinterLink(printer.port, 250000, timeouts=FAST, boot_wait_s=0.2)
        with pytest.raises(PrinterHalted, match="halted"):
            await link.connect()
        assert link.state is LinkState.DISCONNECTED
    finally:
        printer.close()


async def test_recover_after_a_halt(make_sim) -> None:
    sim = make_sim()
    link = link_for(sim)
    await link.connect()
    link.emergency_stop()
    await asyncio.sleep(0.05)
    assert sim.halted_at is not None
    with pytest.raises(NotReady, match="halted"):
        await link.send("G28")  # nothing goes to a halted printer
    await link.recover()  # M999 restarts the firmware; the handshake numbers lines from 1 again
    assert link.state is LinkState.READY
    await link.send("G28")
    assert sim.halted_at is None
    after_restart = [(c.line, c.command) for c in sim.commands()][-5:]
    assert after_restart == [(0, "M110 N0"), (1, "M115"), (2, "M114"), (3, "M155 S2"), (4, "G28")]
    await link.close()


async def test_a_window_too_large_for_the_board_is_found_and_shrunk(make_sim, caplog) -> None:
    # A 64-byte board whose main loop reads nothing while a move waits for the planner, and a host
    # told 127 bytes: lines pile up in its buffer and are cut. The printer asks for each; the
    # governor sees the errors stop with a 63-byte window and keeps it.
    # A queue of 8 commands (reported by ADVANCED_OK): while an M400 blocks, the lines sent after it
    # pile up in the 64-byte buffer, up to the 127 bytes the host was told.
    sim = make_sim(rx_buffer=64, blocking_intake=True, bufsize=8, time_scale=0.01)
    link = link_for(sim, capabilities=Capabilities(rx_buffer_bytes=127))
    await link.connect()
    program = ["G1 F3000"] + [("M400" if i % 10 == 9 else f"G1 X{100 + 2 * (i % 2)}.{i % 10} Y{100 + i % 7}")
                              for i in range(2500)]
    with caplog.at_level("WARNING", logger="ribbond.printer.window"):
        result = await link.stream(program)
    assert executed_program(sim) == program
    assert sim.stats().dropped_bytes > 0, "the board must have lost bytes for the test to mean anything"
    assert result.window_verdict == "overflow" and result.window_bytes == 63, (result, sim.stats())
    assert "set [serial] rx_buffer = 63" in caplog.text
    status = link.status
    assert status.window_bytes == 63 and "set [serial] rx_buffer = 63" in (status.window_advice or ""), \
        "the status says so too (the dashboard shows it)"
    await link.close()


async def test_the_default_window_loses_nothing_on_a_64_byte_board(make_sim) -> None:
    sim = make_sim(rx_buffer=64, blocking_intake=True, bufsize=8, time_scale=0.01)
    link = link_for(sim, capabilities=Capabilities())  # the default, as nothing tells the host
    await link.connect()
    program = ["G1 F3000"] + [("M400" if i % 10 == 9 else f"G1 X{100 + 2 * (i % 2)}.{i % 10} Y{100 + i % 7}")
                              for i in range(1500)]
    result = await link.stream(program)
    assert executed_program(sim) == program
    assert sim.stats().dropped_bytes == 0 and result.resends == 0
    await link.close()


# ---- issue 36: a firmware that times out after a resend request; the report after the ok

@pytest.mark.parametrize("ok_before_output", [False, True])
async def test_a_resent_line_marked_received_without_running_stops_the_stream(make_sim, ok_before_output) -> None:
    """Plain-ok firmware refuses line N, asks for it, never answers the re-sent N (marked received,
    never run) and takes N + 1 next. Its later lines' plain oks would count N as done: instead
    N goes alone, its silence draws M400 + M114, and the position (where line N - 1 left the
    head, not where N would) stops the stream naming N; N never ran and nothing after it went.
    With ``ok_before_output`` the firmware names itself Marlin and prints M114's report after its
    ok: learned at connect, the proof reads it there."""
    sim = make_sim(faults=FaultConfig(ignore_resent_after_lines=300), advanced_ok=False,
                   ok_before_output=ok_before_output)
    link = link_for(sim)
    await link.connect()
    assert link.capabilities.position_report == ("after_ok" if ok_before_output else "line")
    program = moves(1500, seed=4)
    with pytest.raises(ProtocolError, match=r"line (\d+) \(program line (\d+): .*\) never ran") as caught:
        await link.stream(program)
    ignored = sim.stats().ignored_resent_line
    message = str(caught.value)
    assert re.search(r"line (\d+) \(program", message).group(1) == str(ignored)
    index = int(re.search(r"program line (\d+)", message).group(1)) - 1
    assert program[index] in message
    assert ignored not in [c.line for c in sim.commands()], "the named line never ran"
    executed = executed_program(sim)
    assert executed[:index] == program[:index], "everything before it ran, once, in order"
    assert program[index] not in executed and program[index + 1] not in executed, "nothing from it on ran"
    assert link.state is LinkState.READY
    await link.close()


async def test_a_position_report_after_its_ok_on_a_marlin_named_firmware(make_sim) -> None:
    """Issue 36 item 2: a build that names itself Marlin prints M114's report after its ok. The link
    learns it at connect and takes the report there: the position is the move's target."""
    sim = make_sim(ok_before_output=True, dialect="marlin2")
    link = link_for(sim)
    await link.connect()
    assert link.capabilities.firmware_name.startswith("Marlin")
    assert link.capabilities.position_report == "after_ok"
    for x, y in ((12.5, 30.0), (40.25, 7.5)):
        await link.send(f"G1 X{x} Y{y} F6000")
        await link.send("M400")
        pos = await link.query_position()
        assert (pos.x, pos.y) == (x, y)
    await link.close()


def test_stream_command_exits_non_zero_naming_a_resent_line_that_never_ran(make_sim, tmp_path: Path) -> None:
    sim = make_sim(faults=FaultConfig(ignore_resent_after_lines=200), advanced_ok=False)
    program = moves(600)
    path = tmp_path / "part.gcode"
    path.write_text("\n".join(program) + "\n")
    done = run_cli("stream", "--port", sim.port, "--baud", str(sim.config.baud), "--boot-wait", "1",
                   "--timeout", "1", "-q", str(path))
    ignored = sim.stats().ignored_resent_line
    assert ignored > 0
    assert done.returncode == 1, done.stdout
    assert re.search(rf"line {ignored} \(program line \d+: .*\) never ran", done.stderr), done.stderr
    assert "lines acknowledged" not in done.stdout
