"""`make demo`: stream an example print program to the simulated printer over a real pty.

Starts the simulator (`python -m sim`) as its own process, as firmware runs on its own board;
streams the example program with the operator command (`python -m ribbond.printer stream`); then
prints what the simulator executed and the path of a PNG of what it deposited. Everything lands in
``out/demo/``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from sim.process import SimProcess  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "demo"
BAUD = 250000
TIME_SCALE = 0.05  # 20× faster than the real machine, so the demo takes seconds


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    program = OUT / "ribbons.gcode"
    subprocess.run([sys.executable, str(ROOT / "examples" / "demo_program.py"), str(program)], check=True)
    lines = sum(1 for line in program.read_text().splitlines() if line.split(";")[0].strip())
    png = OUT / "deposits.png"
    args = ["--baud", str(BAUD), "--time-scale", str(TIME_SCALE), "--record", str(OUT / "record.jsonl")]
    with SimProcess(args, cwd=ROOT) as printer:
        print(f"simulated printer on {printer.port} ({BAUD} baud, time scale {TIME_SCALE})")
        print(f"streaming {program.relative_to(ROOT)} ({lines} commands)")
        started = time.monotonic()
        streamed = subprocess.run(
            [sys.executable, "-m", "ribbond.printer", "stream", "--port", printer.port, "--baud", str(BAUD),
             str(program)],
            cwd=ROOT,
        )
        elapsed = time.monotonic() - started
        if streamed.returncode != 0:
            print(f"error: streaming failed (exit {streamed.returncode})", file=sys.stderr)
            return streamed.returncode
        stats = printer.stats()
        printer.request({"cmd": "render", "path": str(png)})
    print()
    print("what the simulator executed")
    for key in ("commands_executed", "lines_received", "resends_requested", "checksum_errors",
                "dropped_bytes", "starvations", "segments", "extruded_mm"):
        if key in stats:
            print(f"  {key.replace('_', ' ')}: {stats[key]}")
    print(f"  wall time: {elapsed:.1f} s")
    print(f"deposits: {png.relative_to(ROOT) if png.is_relative_to(ROOT) else png}")
    return 0


if __name__ == "__main__":
    os.chdir(ROOT)
    sys.exit(main())
