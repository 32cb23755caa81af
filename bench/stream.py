"""Streaming throughput of the printer link against the simulated printer (a benchmark, not a test).

For 115200 and 250000 baud, windowed and ping-pong, two programs of short G1 moves:

* link-bound: moves the printer executes in no time, so the serial line is the only limit;
* balanced: moves that each take as long as 1/0.95 of a line's wire time, so the printer consumes
  lines at 95 % of what the link can carry. A host that keeps the link busy keeps the planner fed;
  one that does not starves it.

Each row prints lines per second, the link limit (baud / 10 / mean encoded line length) and their
ratio, and the planner starvations the simulator counted (moments its planner ran empty while the
host still had lines). Goal (issue 2): windowed ≥ 0.9 of the link limit with zero starvations at
250000 baud.

    python bench/stream.py [--lines N] [--quick]
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ribbond.printer import PrinterLink, Timeouts, codec  # noqa: E402
from sim.process import SimProcess  # noqa: E402

BALANCED_LOAD = 0.95
FEED = 6000.0  # mm/min
HANDSHAKE_LINES = 3  # M110, M115, M155: the program's first line number


@dataclass
class Row:
    baud: int
    mode: str
    program: str
    lines: int
    lines_per_s: float
    link_limit: float
    starvations: int
    dropped_bytes: int
    resends: int

    @property
    def ratio(self) -> float:
        return self.lines_per_s / self.link_limit


def program(count: int, step_mm: float) -> list[str]:
    """Short moves back and forth along X, each ``step_mm`` long."""
    lines = []
    x = 100.0
    for i in range(count):
        x += step_mm if (i // 50) % 2 == 0 else -step_mm
        lines.append(f"G1 X{x:.3f} Y{100 + (i % 7) * 0.001:.3f} F{FEED:.0f}")
    return lines


def mean_encoded_length(lines: list[str]) -> float:
    return sum(len(codec.encode(HANDSHAKE_LINES + i, c)) for i, c in enumerate(lines)) / len(lines)


async def run(baud: int, ping_pong: bool, kind: str, count: int) -> Row:
    # Size the moves from the wire time of a line of this program (the step barely changes it).
    probe = program(count, 0.1)
    line_s = mean_encoded_length(probe) * 10 / baud
    if kind == "link-bound":
        time_scale = 1e-6
        step = 0.1
    else:
        time_scale = 1.0
        step = FEED / 60 * line_s / BALANCED_LOAD
    lines = program(count, step)
    limit = baud / 10 / mean_encoded_length(lines)
    # The simulator runs as its own process, as firmware runs on its own board.
    with SimProcess(["--baud", str(baud), "--time-scale", str(time_scale)], cwd=ROOT) as sim:
        link = PrinterLink(sim.port, baud, ping_pong=ping_pong, boot_wait_s=1.0, timeouts=Timeouts(default_s=5))
        await link.connect()
        await link.send("G28")
        await link.send(f"G1 X100 Y100 F{FEED:.0f}")  # to the program's start, outside the timing
        await link.send("M400")
        sim.request({"cmd": "reset_stats"})
        started = time.monotonic()
        result = await link.stream(lines)
        elapsed = time.monotonic() - started
        stats = sim.stats()
        await link.close()
    return Row(baud, "ping-pong" if ping_pong else "windowed", kind, count, result.lines / elapsed, limit,
               stats["starvations"], stats["dropped_bytes"], result.resends)


async def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lines", type=int, default=4000, help="lines per run (default 4000)")
    parser.add_argument("--quick", action="store_true", help="250000 baud only")
    args = parser.parse_args()
    bauds = [250000] if args.quick else [115200, 250000]
    rows = []
    print(f"{'baud':>7} {'mode':>9} {'program':>10} {'lines/s':>8} {'limit':>7} {'ratio':>6} "
          f"{'starved':>7} {'dropped':>7} {'resends':>7}")
    for baud in bauds:
        for kind in ("link-bound", "balanced"):
            for ping_pong in (False, True):
                row = await run(baud, ping_pong, kind, args.lines)
                rows.append(row)
                print(f"{row.baud:>7} {row.mode:>9} {row.program:>10} {row.lines_per_s:>8.0f} {row.link_limit:>7.0f} "
                      f"{row.ratio:>6.2f} {row.starvations:>7} {row.dropped_bytes:>7} {row.resends:>7}", flush=True)
    goal = {r.program: r for r in rows if r.baud == 250000 and r.mode == "windowed"}
    bound, balanced = goal["link-bound"], goal["balanced"]
    met = bound.ratio >= 0.9 and balanced.ratio >= 0.9 and balanced.starvations == 0
    print(f"\ngoal at 250000 baud, windowed: ratio {bound.ratio:.2f} link-bound and {balanced.ratio:.2f} balanced "
          f"(each >= 0.90), {balanced.starvations} starvations while the printer was fed (= 0): "
          f"{'met' if met else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
