"""Fixtures for the daemon's end-to-end tests: real processes only.

A simulated printer (``python -m sim`` on a real pty, driven through its control socket), a real
``ribbond`` process reading a TOML configuration, and real HTTP with httpx. Nothing is mocked.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.mesh.files import write_obj
from ribbond.design.surfaces import saddle
from sim.process import SimProcess
from tests.conftest import COMPILE_CACHE_ENV

ROOT = Path(__file__).resolve().parents[2]

#: Simulator speed: 50× faster than the machine (heating takes ~1.6 s, a 145 s front ~3 s).
TIME_SCALE = 0.02
BAUD = 250000
#: Small designs: fewer ribbons, short programs.
PARAMETERS = {"size": {"bbox_diagonal": 70}}
#: The daemon's compiles predict the deployed shape (the default; the harness turns it off elsewhere),
#: the forward layout's (the optimization against it costs up to 45 s a compile; tests/deploy/test_optimize.py)
PREDICT = "[design]\npredict = true\noptimize = false\n"
#: The profile's frame centre (ultimaker2-tpu): the flip is about the line x = 110.
CENTER = (110.0, 110.0)
#: Commands the link sends on its own (handshake, probes): not program lines.
HOST_COMMANDS = ("M110", "M115", "M155", "M105", "M114")
TERMINAL = {"done", "cancelled", "failed"}


# ---------------------------------------------------------------------------------- the printer


class Sim:
    """A simulator process, and which side of its frame is up (its flip toggles sides)."""

    def __init__(self) -> None:
        self.process = SimProcess(["--time-scale", str(TIME_SCALE), "--baud", str(BAUD)], cwd=ROOT).start()
        self.port = self.process.port
        self.side = "front"

    def request(self, request: dict[str, Any]) -> dict[str, Any]:
        return self.process.request(request)

    def flip(self, dx: float = 0.0, dy: float = 0.0, rotation_deg: float = 0.0) -> dict[str, Any]:
        pose = self.request({"cmd": "flip", "dx": dx, "dy": dy, "rotation_deg": rotation_deg})["pose"]
        self.side = pose["side"]
        return pose

    def ensure_front(self) -> None:
        """Front side up, no misalignment (the identity pose the simulator starts with)."""
        if self.side != "front":
            self.flip()
        assert self.side == "front"

    def segments(self) -> list[dict[str, Any]]:
        return list(self.request({"cmd": "segments"})["segments"])

    def commands(self) -> list[dict[str, Any]]:
        return list(self.request({"cmd": "commands"})["commands"])

    def queued(self) -> list[str]:
        """The firmware's command queue: the one running first, then those received behind it."""
        return list(self.request({"cmd": "queued"})["queued"])

    def program_commands(self) -> list[str]:
        """Executed commands, without the link's own handshake and probes."""
        return [c["command"] for c in self.commands() if c["command"].split()[0].upper() not in HOST_COMMANDS]

    def stop(self) -> None:
        self.process.stop()


# ---------------------------------------------------------------------------------- the daemon


class Daemon:
    """``python -m ribbond --config FILE`` in its own process, with an httpx client on its API."""

    def __init__(self, state_dir: Path, port: str, *, api: str = "", extra: str = "",
                 token: str | None = None, cache: bool = True) -> None:
        """``api``: more lines of the ``[api]`` table; ``extra``: more tables (TOML text); ``cache``:
        compile through the session's shared compile cache (``COMPILE_CACHE_ENV``), False: every
        compile made afresh (``[design] cache_dir = ""``), for the tests of the compile itself."""
        self.state_dir = state_dir
        self.state_dir.mkdir(parents=True, exist_ok=True)
        self.config = state_dir / "ribbond.toml"
        if "[design]" not in extra:            # the deploy stage costs 5-10 s a compile; see PREDICT
            extra = f"{extra}\n[design]\npredict = false\n"
        shared = os.environ.get(COMPILE_CACHE_ENV, "")
        cache_line = f"cache_dir = {json.dumps(shared if cache else '')}" if shared or not cache else ""
        if "cache_dir" not in extra:
            extra = extra.replace("[design]\n", f"[design]\n{cache_line}\n", 1)
        self.config.write_text(
            f'state_dir = "{state_dir}"\nlog_level = "info"\n'
            f'[serial]\nport = "{port}"\nbaud = {BAUD}\n'
            f'[api]\nhost = "127.0.0.1"\nport = 0\n{api}\n{extra}\n', encoding="utf-8")
        self.log_path = state_dir / "ribbond.log"
        self.token = token
        self.proc: subprocess.Popen[bytes] | None = None
        self.url = ""
        self.client: httpx.Client | None = None
        self.runs = 0

    def start(self, timeout: float = 30.0) -> Daemon:
        url_file = self.state_dir / "api.url"
        url_file.unlink(missing_ok=True)          # a killed daemon leaves its address behind
        self.runs += 1
        log = self.log_path.open("ab")
        log.write(f"\n===== run {self.runs} =====\n".encode())
        log.flush()
        self.proc = subprocess.Popen([sys.executable, "-m", "ribbond", "--config", str(self.config)],
                                     cwd=ROOT, stdout=log, stderr=log,
                                     env={**os.environ, "PYTHONUNBUFFERED": "1"})
        log.close()
        deadline = time.monotonic() + timeout
        while not url_file.exists():
            if self.proc.poll() is not None:
                raise RuntimeError(f"ribbond exited with {self.proc.returncode}:\n{self.log_tail()}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"ribbond did not write api.url in {timeout:.0f} s:\n{self.log_tail()}")
            time.sleep(0.05)
        # The file is written in one call; wait until the line is complete.
        while not (text := url_file.read_text(encoding="utf-8")).endswith("\n"):
            time.sleep(0.01)
        self.url = text.strip()
        headers = {"Authorization": f"Bearer {self.token}"} if self.token else {}
        self.client = httpx.Client(base_url=self.url, timeout=60.0, headers=headers)
        return self

    def wait_printer(self, timeout: float = 30.0) -> None:
        """Until the daemon's link to the printer is up."""
        assert self.client is not None
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            status = self.client.get("/printer").json()
            if status.get("state") in ("ready", "streaming", "paused"):
                return
            time.sleep(0.1)
        raise RuntimeError(f"the printer did not connect in {timeout:.0f} s: {status}\n{self.log_tail()}")

    def log_tail(self, chars: int = 4000) -> str:
        try:
            return self.log_path.read_text(encoding="utf-8", errors="replace")[-chars:]
        except OSError:
            return "(no log)"

    def _close_client(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None

    def kill(self) -> None:
        """SIGKILL: no shutdown code runs, as in a crash or a power cut."""
        assert self.proc is not None
        self._close_client()
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(10)
        self.proc = None

    def stop(self) -> None:
        self._close_client()
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc = None


# ---------------------------------------------------------------------------------- API helpers


def submit(client: httpx.Client, mesh: Path, *, start: bool, parameters: dict[str, Any] | None = None) -> str:
    with mesh.open("rb") as handle:
        r = client.post("/jobs", files={"mesh": (mesh.name, handle)},
                        data={"parameters": json.dumps(parameters or PARAMETERS), "start": str(start).lower()})
    assert r.status_code == 201, r.text
    return str(r.json()["id"])


def fresh_copy(mesh: Path, folder: Path) -> Path:
    """``mesh`` in ``folder`` (the same name) with a comment line of its own appended: the same surface
    in bytes no compile cache holds, so that its compile runs for real beside cached ones (for a
    test that watches a compile: its stages, the page while it compiles)."""
    copy = folder / mesh.name
    copy.write_bytes(mesh.read_bytes() + f"# compiled afresh: {uuid.uuid4().hex}\n".encode())
    return copy


#: The stage of a queued job waiting for the operator to confirm a fresh frame (``ribbond.daemon.components.frame``).
FRESH_FRAME_STAGE = "waiting for a fresh frame"


def frame_ready(client: httpx.Client) -> dict[str, Any]:
    """The operator loads a fresh stretched frame and confirms it (``ribbonctl frame-ready``)."""
    r = client.post("/printer/frame-ready")
    assert r.status_code == 200, r.text
    return dict(r.json())


def at_gate(job: dict[str, Any]) -> bool:
    """The job waits for a fresh frame (ready, queued, its stage says so)."""
    return job["state"] == "ready" and job["start_when_ready"] and job.get("stage") == FRESH_FRAME_STAGE


def wait_for(client: httpx.Client, job: str, states: set[str] | str, *, timeout: float = 60.0,
             poll: float = 0.05, until: Any = None, fresh_frame: bool = True) -> dict[str, Any]:
    """Poll the job until its state is in ``states`` (and ``until(job)`` holds); fail on a
    terminal state that was not asked for. ``fresh_frame``: when the job waits for a fresh frame
    on the way, load one and confirm it, as the operator at the printer does (``frame_ready``)."""
    wanted = {states} if isinstance(states, str) else set(states)
    deadline = time.monotonic() + timeout
    seen: list[str] = []
    while True:
        j = client.get(f"/jobs/{job}").json()
        if not seen or seen[-1] != j["state"]:
            seen.append(j["state"])
        if j["state"] in wanted and (until is None or until(j)):
            return dict(j)
        if fresh_frame and at_gate(j):
            frame_ready(client)
            continue
        if j["state"] in (TERMINAL | {"interrupted"}) - wanted:
            raise AssertionError(f"job {job} ended {j['state']} ({j.get('error')}) waiting for {wanted}; "
                                 f"states seen {seen}")
        if time.monotonic() > deadline:
            raise AssertionError(f"job {job} did not reach {wanted} in {timeout:.0f} s; states seen {seen}: {j}")
        time.sleep(poll)


def cancel_leftovers(client: httpx.Client) -> None:
    """Cancel whatever a test left queued or holding the printer, so the next test has it free."""
    for j in client.get("/jobs").json():
        if j["state"] not in TERMINAL:
            client.post(f"/jobs/{j['id']}/cancel")
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        if all(j["state"] in TERMINAL for j in client.get("/jobs").json()):
            return
        time.sleep(0.1)


# ---------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="session")
def meshes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``two_sided``: a saddle with 2 front and 17 back ribbons at 70 mm (front 268 lines, back
    ~1800). ``one_sided``: a saddle whose ribbons are all on the front (~1800 lines, ~3 s here)."""
    folder = tmp_path_factory.mktemp("meshes")
    out = {}
    for name, (kx, ky) in {"two_sided": (1 / 50, 1 / 50), "one_sided": (1 / 80, 1 / 40)}.items():
        V, F = saddle(80.0, kx, ky, rings=12)
        path = folder / f"{name}.obj"
        write_obj(path, V, F)
        out[name] = path
    return out


@pytest.fixture(scope="module")
def shared_sim() -> Iterator[Sim]:
    sim = Sim()
    try:
        yield sim
    finally:
        sim.stop()


@contextlib.contextmanager
def running(state_dir: Path, port: str, **options: Any) -> Iterator[Daemon]:
    """A daemon on the printer at ``port``, started and connected (its client ready), stopped after."""
    daemon = Daemon(state_dir, port, **options)
    try:
        daemon.start()
        daemon.wait_printer()
        yield daemon
    finally:
        daemon.stop()


@contextlib.contextmanager
def own_printer(state_dir: Path, **options: Any) -> Iterator[tuple[Sim, Daemon]]:
    """A simulator of its own and a daemon on it (``running``), for tests that kill, restart or
    stop the daemon; both stopped after (stopping a killed daemon is a no-op)."""
    sim = Sim()
    try:
        with running(state_dir, sim.port, **options) as daemon:
            yield sim, daemon
    finally:
        sim.stop()


@pytest.fixture(scope="module")
def shared_daemon(shared_sim: Sim, tmp_path_factory: pytest.TempPathFactory,
                  request: pytest.FixtureRequest) -> Iterator[Daemon]:
    """The module's daemon; its compiles skip the deploy stage unless the module sets
    ``DAEMON_EXTRA = PREDICT`` (the tests of the prediction itself), and go through the session's
    compile cache unless it sets ``DAEMON_CACHE = False`` (the tests that watch a compile run)."""
    extra = getattr(request.module, "DAEMON_EXTRA", "")
    cache = getattr(request.module, "DAEMON_CACHE", True)
    with running(tmp_path_factory.mktemp("ribbond-shared"), shared_sim.port, extra=extra, cache=cache) as daemon:
        yield daemon


@pytest.fixture
def api(shared_daemon: Daemon, shared_sim: Sim) -> Iterator[httpx.Client]:
    """The shared daemon's client; a fresh frame (front up) loaded and confirmed before, no job left
    running after."""
    shared_sim.ensure_front()
    assert shared_daemon.client is not None
    frame_ready(shared_daemon.client)
    try:
        yield shared_daemon.client
    finally:
        if shared_daemon.client is not None:
            cancel_leftovers(shared_daemon.client)
