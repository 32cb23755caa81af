"""``python -m sim``: help, the pty path on the first line, record, control socket, render."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.testing import PtyHost

ROOT = Path(__file__).resolve().parent.parent


def run_sim(*args: str) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "sim", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_help_documents_every_option() -> None:
    out = subprocess.run([sys.executable, "-m", "sim", "--help"], cwd=ROOT, capture_output=True,
                         text=True, check=True, env=dict(os.environ, PYTHONPATH=str(ROOT))).stdout
    for option in ("--baud", "--time-scale", "--no-advanced-ok", "--no-ok-after-resend",
                   "--rx-buffer", "--bufsize", "--planner-blocks", "--keepalive", "--seed",
                   "--corrupt-rate", "--drop-ok-rate", "--spurious-resend-rate",
                   "--unsolicited-rate", "--slow-rate", "--slow-delay", "--reset-after-lines",
                   "--disconnect-after-lines", "--runaway-after-lines", "--frame-center",
                   "--flip-axis", "--record", "--render", "--control"):
        assert option in out, option


def test_bad_option_rejected() -> None:
    proc = subprocess.run([sys.executable, "-m", "sim", "--corrupt-rate", "2"], cwd=ROOT,
                          capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 2 and "probability" in proc.stderr


class Control:
    def __init__(self, path: str) -> None:
        deadline = time.monotonic() + 5.0
        while not os.path.exists(path):
            assert time.monotonic() < deadline, "control socket never appeared"
            time.sleep(0.01)
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.connect(path)
        self.file = self.sock.makefile("rw")

    def __call__(self, **request: object) -> dict:
        self.file.write(json.dumps(request) + "\n")
        self.file.flush()
        return json.loads(self.file.readline())

    def close(self) -> None:
        self.file.close()
        self.sock.close()


def test_program_serves_records_controls_and_renders(tmp_path: Path) -> None:
    record, png, sock = tmp_path / "rec.jsonl", tmp_path / "out.png", tmp_path / "ctl.sock"
    png2 = tmp_path / "now.png"
    proc = run_sim("--time-scale", "0.001", "--baud", "1000000", "--record", str(record),
                   "--render", str(png), "--control", str(sock), "--frame-center", "100,100")
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline().strip()
        assert first.startswith("/dev/pts/"), first
        ctl = Control(str(sock))
        with PtyHost(first) as host:
            host.wait_banner()
            host.command("M83")
            host.command("G1 X10 Y10 F6000")
            host.command("G1 X20 Y10 E1", 1)
            host.command("M400")
            assert ctl(cmd="flip", dx=0.5, dy=0, rotation_deg=0)["pose"]["side"] == "back"
            host.command("G1 X180 Y10 E1")
            host.command("M400")
            stats = ctl(cmd="stats")
            assert stats["ok"] and stats["stats"]["segments"] == 2
            segs = ctl(cmd="segments")["segments"]
            assert [s["side"] for s in segs] == ["front", "back"]
            # p = Mirror(q) + offset: 180 = (200 - qx) + 0.5, so qx = 20.5.
            assert segs[1]["fx1"] == pytest.approx(20.5)
            cmds = ctl(cmd="commands")["commands"]
            assert [c["command"] for c in cmds][-2:] == ["G1 X180 Y10 E1", "M400"]
            assert ctl(cmd="render", path=str(png2)) == {"ok": True, "path": str(png2)}
            assert ctl(cmd="bogus")["ok"] is False
            assert ctl(cmd="reset") == {"ok": True}
            host.wait_banner()
            assert ctl(cmd="runaway") == {"ok": True}
            assert host.read_quiet()[-1] == "Error:Printer halted. kill() called!"
            assert ctl(cmd="disconnect") == {"ok": True}
        ctl.close()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    rows = [json.loads(s) for s in record.read_text().splitlines()]
    assert rows[2] == {"line": 1, "command": "G1 X20 Y10 E1", "time": rows[2]["time"]}
    assert rows[0]["line"] is None and rows[0]["command"] == "M83"
    assert png.read_bytes()[:4] == b"\x89PNG" and png2.read_bytes()[:4] == b"\x89PNG"
    assert not sock.exists()


def test_sigint_stops_program() -> None:
    proc = run_sim()
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/pts/") and os.path.exists(path)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_sim_process_wrapper_drives_the_control_socket() -> None:
    from sim.process import SimProcess

    root = Path(__file__).resolve().parent.parent
    with SimProcess(["--baud", "1000000", "--time-scale", "0.001"], cwd=root) as printer:
        assert printer.port.startswith("/dev/")
        assert printer.request({"cmd": "port"})["port"] == printer.port
        assert printer.stats()["commands_executed"] == 0
        pose = printer.request({"cmd": "flip", "dx": 0.5, "dy": -0.25, "rotation_deg": 1.0})["pose"]
        assert pose  # the new pose of the fabric
        with pytest.raises(RuntimeError, match="render"):
            printer.request({"cmd": "render"})  # no path: refused with the reason
    assert not Path(printer.control_path).exists()
