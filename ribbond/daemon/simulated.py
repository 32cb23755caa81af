"""``ribbond --simulate``: the daemon on the simulated printer, for trying ribbond without one.

The simulator (``python -m sim``, the project's own, which imports nothing of ribbond) is started as
a child process; the first line it prints is its pty, which becomes the configuration's ``[serial]
port`` (its ``baud`` is passed to the simulator, so the two agree). The child is stopped when the
daemon exits, and on Linux also when the daemon dies without cleaning up (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import shlex
import signal
import subprocess
import sys
from pathlib import Path

#: Where ``--simulate`` keeps its jobs when no ``--config`` names a state directory: never a real
#: printer's store (``$XDG_STATE_HOME/ribbond-sim``, else ``~/.local/state/ribbond-sim``).
SIM_STATE_DIR = Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state") / "ribbond-sim"
#: Seconds the simulator may take to print its pty.
START_TIMEOUT_S = 30.0


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    """Linux: the child gets SIGTERM when the daemon dies (even by SIGKILL)."""
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)      # PR_SET_PDEATHSIG


def start_simulator(baud: int, extra: str = "") -> tuple[subprocess.Popen[str], str]:
    """``python -m sim --baud BAUD EXTRA…`` as a child; the process and its pty path.

    Raises
    ------
    ValueError
        ``extra`` cannot be split into arguments, or the simulator did not print a pty (its
        message, e.g. an unknown option, is in the error).
    """
    try:
        args = shlex.split(extra)
    except ValueError as exc:
        raise ValueError(f"--sim-args {extra!r}: {exc}") from None
    # (its stderr is the daemon's: what it says goes to the same terminal or journal)
    proc = subprocess.Popen([sys.executable, "-m", "sim", "--baud", str(baud), *args], stdout=subprocess.PIPE,
                            text=True, preexec_fn=_die_with_parent if sys.platform == "linux" else None)
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if not line.startswith("/dev/"):
        stop_simulator(proc)
        raise ValueError(f"the simulator did not start (python -m sim {' '.join(args)}; its message is "
                         f"above): {line or 'no pty printed'}")
    return proc, line


def stop_simulator(proc: subprocess.Popen[str]) -> None:
    """SIGTERM, then SIGKILL after 5 s; its pipe closed."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()
