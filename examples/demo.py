"""`make demo`: stream an example print program to the simulated printer over a real pty.

Starts the simulator (`python -m sim`) as its own process, streams the example program with the
operator command (`python -m ribbond.printer stream`), then prints what the simulator executed and
the path of a PNG of what it deposited. Everything lands in ``out/demo/``.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "demo"
BAUD = 250000
TIME_SCALE = 0.05  # 20× faster than the real machine, so the demo takes seconds


def control(sock_path: Path, request: dict) -> dict:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(30)
        sock.connect(str(sock_path))
        sock.sendall((json.dumps(request) + "\n").encode())
        data = b""
        while not data.endswith(b"\n"):
            chunk = sock.recv(1 << 20)
            if not chunk:
                break
            data += chunk
    return json.loads(data)


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    program = OUT / "ribbons.gcode"
    subprocess.run([sys.executable, str(ROOT / "examples" / "demo_program.py"), str(program)], check=True)
    lines = sum(1 for line in program.read_text().splitlines() if line.split(";")[0].strip())
    sock_path = OUT / "sim.sock"
    png = OUT / "deposits.png"
    sim = subprocess.Popen(
        [sys.executable, "-m", "sim", "--baud", str(BAUD), "--time-scale", str(TIME_SCALE),
         "--record", str(OUT / "record.jsonl"), "--control", str(sock_path)],
        cwd=ROOT, stdout=subprocess.PIPE, text=True,
    )
    try:
        assert sim.stdout is not None
        port = sim.stdout.readline().strip()
        if not port.startswith("/dev/"):
            print(f"error: the simulator did not start (said {port!r})", file=sys.stderr)
            return 1
        print(f"simulated printer on {port} ({BAUD} baud, time scale {TIME_SCALE})")
        print(f"streaming {program.relative_to(ROOT)} ({lines} commands)")
        started = time.monotonic()
        streamed = subprocess.run(
            [sys.executable, "-m", "ribbond.printer", "stream", "--port", port, "--baud", str(BAUD), str(program)],
            cwd=ROOT,
        )
        elapsed = time.monotonic() - started
        if streamed.returncode != 0:
            print(f"error: streaming failed (exit {streamed.returncode})", file=sys.stderr)
            return streamed.returncode
        stats = control(sock_path, {"cmd": "stats"})
        control(sock_path, {"cmd": "render", "path": str(png)})
    finally:
        sim.send_signal(signal.SIGTERM)
        sim.wait(timeout=10)
    stats = stats.get("stats", stats)
    print()
    print("what the simulator executed")
    for key in ("commands_executed", "lines_received", "resends_requested", "checksum_errors",
                "dropped_bytes", "starvations", "segments"):
        if key in stats:
            print(f"  {key.replace('_', ' ')}: {stats[key]}")
    print(f"  wall time: {elapsed:.1f} s")
    print(f"deposits: {png.relative_to(ROOT) if png.is_relative_to(ROOT) else png}")
    return 0


if __name__ == "__main__":
    os.chdir(ROOT)
    sys.exit(main())
