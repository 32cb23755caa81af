"""``ribbond --simulate`` (issue 36 item 13): one command runs the daemon on the simulated printer.

A real ``ribbond --simulate`` process: it starts ``python -m sim`` as its child, connects to the pty
the child printed (the simulator's own M115 answers), prints a plain program through it to ``done``,
and stops the child when it stops; a simulator that cannot start is a configuration error (exit 2).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from .conftest import ROOT

pytestmark = pytest.mark.timeout(120)


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie has exited (its parent, the daemon, reaps it)
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        return f.read().split(") ", 1)[1][0] != "Z"


def test_ribbond_simulate_prints_on_its_own_simulator_and_stops_it(tmp_path: Path) -> None:
    state = tmp_path / "state"
    config = tmp_path / "ribbond.toml"
    config.write_text(f'state_dir = "{state}"\n[serial]\nport = "/dev/nonexistent"\nbaud = 250000\n'
                      '[api]\nhost = "127.0.0.1"\nport = 0\n[design]\npredict = false\n', encoding="utf-8")
    log_path = tmp_path / "ribbond.log"
    with log_path.open("wb") as log:
        proc = subprocess.Popen([sys.executable, "-m", "ribbond", "--config", str(config), "--simulate",
                                 "--sim-args", "--time-scale 0.02"], cwd=ROOT, stdout=log, stderr=log,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        deadline = time.monotonic() + 30
        while not (state / "api.url").exists() or not (state / "api.url").read_text().endswith("\n"):
            assert proc.poll() is None, log_path.read_text()
            assert time.monotonic() < deadline, log_path.read_text()
            time.sleep(0.05)
        url = (state / "api.url").read_text().strip()
        text = log_path.read_text()
        found = re.search(r"simulated printer on (/dev/\S+) \(python -m sim, pid (\d+)\)", text)
        assert found, text
        pty, pid = found.group(1), int(found.group(2))
        with httpx.Client(base_url=url, timeout=30) as api:
            while (printer := api.get("/printer").json())["state"] != "ready":
                assert time.monotonic() < deadline, printer
                time.sleep(0.1)
            assert "(sim)" in printer["firmware"], printer          # the simulator's M115
            assert f"printer connected on {pty}" in log_path.read_text()   # the pty the child printed
            program = "G28\nG90\nG0 Z5 F600\n" + "".join(f"G0 X{60 + 10 * k} Y80 F3000\n" for k in range(6))
            r = api.post("/jobs", files={"gcode": ("line.gcode", program.encode())},
                         data={"start": "true", "same_frame": "true"})
            assert r.status_code == 201, r.text
            job = r.json()["id"]
            while (j := api.get(f"/jobs/{job}").json())["state"] != "done":
                assert j["state"] not in ("failed", "cancelled", "interrupted"), j
                assert time.monotonic() < deadline + 30, j
                time.sleep(0.1)
        assert alive(pid)
    finally:
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(30)
    assert code == 0, log_path.read_text()
    deadline = time.monotonic() + 10
    while alive(pid):
        assert time.monotonic() < deadline, "the simulator outlived ribbond --simulate"
        time.sleep(0.05)


def test_a_simulator_that_cannot_start_is_a_configuration_error(tmp_path: Path) -> None:
    config = tmp_path / "ribbond.toml"
    config.write_text(f'state_dir = "{tmp_path / "state"}"\n[api]\nport = 0\n', encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "ribbond", "--config", str(config), "--simulate",
                           "--sim-args=--no-such-option"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "the simulator did not start" in proc.stderr and "--no-such-option" in proc.stderr, proc.stderr
