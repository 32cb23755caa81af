"""Counters a test or a benchmark reads to judge how a host drove the printer."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Stats"]


@dataclass
class Stats:
    """Counters since start or the last ``reset_stats()``."""

    lines_received: int = 0
    """Non-empty lines taken from the receive buffer (before any check)."""
    commands_executed: int = 0
    checksum_errors: int = 0
    """``checksum mismatch`` and ``No Checksum with line number`` errors."""
    line_number_errors: int = 0
    resends_requested: int = 0
    """Every ``Resend:`` printed, including spurious ones."""
    dropped_bytes: int = 0
    """Bytes lost because the receive buffer was full when they arrived."""
    oks_sent: int = 0
    oks_dropped: int = 0
    starvations: int = 0
    starved_s: float = 0.0
    """Wall seconds the planner sat empty before each starvation's block."""
    bytes_in: int = 0
    bytes_out: int = 0
    planner_peak: int = 0
    """Most moves ever queued in the planner at once."""
    # Beyond the required counters:
    spurious_resends: int = 0
    corrupted_lines: int = 0
    skipped_lines: int = 0
    swallowed_line: int = -1
    """The line number the swallow_resent fault took without running it (-1: none)."""
    ignored_resent_line: int = -1
    """The line number the ignore_resent fault marked received without running it (-1: none)."""
    cut_tails_queued: int = 0
    """Tails of flushed lines queued as unnumbered commands (cut_tail "marlin2")."""
    unsolicited_lines: int = 0
    slow_lines: int = 0
    busy_lines: int = 0
    resets: int = 0
    halts: int = 0
    disconnects: int = 0
    connections: int = 0
    """Times a host opened the port (each one reboots the board, as DTR does)."""
    boot_lost_bytes: int = 0
    """Bytes that arrived while the board was (re)booting, hence lost."""
    segments: int = 0
    extruded_mm: float = 0.0
    queue_peak: int = 0
    rx_peak: int = 0
