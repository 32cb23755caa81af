"""The simulator as its own process, driven through its control socket.

Real firmware runs on its own hardware; benchmarks, demos and end-to-end tests run the simulator the
same way, so that the host's pauses (garbage collection, the GIL) and the printer's are independent.

    with SimProcess(["--baud", "250000", "--time-scale", "0.05"]) as printer:
        printer.port                     # the pty to open
        printer.camera_url               # with --camera-port: http://127.0.0.1:PORT/
        printer.request({"cmd": "flip", "dx": 0.3})
        printer.stats()                  # dict of the simulator's counters
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["SimProcess"]


class SimProcess:
    """``python -m sim`` with ``args``, its pty path read from its first output line.

    Parameters
    ----------
    args
        Options of ``python -m sim`` (``--control`` is added).
    cwd
        Working directory of the process (the repository root when the project is not installed).
    """

    def __init__(self, args: list[str] | None = None, *, cwd: str | Path | None = None,
                 startup_timeout_s: float = 30.0) -> None:
        self._dir = tempfile.TemporaryDirectory(prefix="ribbond-sim-")
        self.control_path = str(Path(self._dir.name) / "control.sock")
        self._args = [*(args or []), "--control", self.control_path]
        self._cwd = cwd
        self._startup_timeout_s = startup_timeout_s
        self._process: subprocess.Popen[str] | None = None
        self.port = ""
        #: The camera's base address (``--camera-port``), else "".
        self.camera_url = ""

    def start(self) -> SimProcess:
        self._process = subprocess.Popen(
            [sys.executable, "-m", "sim", *self._args], cwd=self._cwd,
            stdout=subprocess.PIPE, text=True,
        )
        assert self._process.stdout is not None
        line = self._process.stdout.readline().strip()
        if not line.startswith("/dev/"):
            self.stop()
            raise RuntimeError(f"the simulator did not start (it printed {line!r})")
        self.port = line
        if "--camera-port" in self._args:
            url = self._process.stdout.readline().strip()
            if not url.startswith("http://"):
                self.stop()
                raise RuntimeError(f"the simulator's camera did not start (it printed {url!r})")
            self.camera_url = url
        return self

    def request(self, request: dict[str, Any], timeout_s: float = 60.0) -> dict[str, Any]:
        """Send one control request and return the answer; raises RuntimeError if it failed."""
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(timeout_s)
            sock.connect(self.control_path)
            sock.sendall((json.dumps(request) + "\n").encode())
            data = bytearray()
            while not data.endswith(b"\n"):
                chunk = sock.recv(1 << 20)
                if not chunk:
                    break
                data += chunk
        answer: dict[str, Any] = json.loads(data)
        if not answer.get("ok", False):
            raise RuntimeError(f"simulator refused {request.get('cmd')!r}: {answer.get('error')}")
        return answer

    def stats(self) -> dict[str, Any]:
        return dict(self.request({"cmd": "stats"})["stats"])

    def stop(self) -> None:
        """SIGTERM (the simulator writes its --record and --render outputs), then wait."""
        if self._process is not None and self._process.poll() is None:
            self._process.send_signal(signal.SIGTERM)
            try:
                self._process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        if self._process is not None and self._process.stdout is not None:
            self._process.stdout.close()
        self._process = None
        self._dir.cleanup()

    def __enter__(self) -> SimProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
