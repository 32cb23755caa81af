"""The fresh-frame gate between jobs (issue 22, item 1), end to end: a real simulator on its pty,
real ribbond processes, real HTTP.

Two jobs queued: when the first ends (done, cancelled, failed on the printer) the second does not
heat over the fabric the first printed on; it waits, ``ready``, until the operator confirms a fresh
frame (``frame-ready``). What "does not heat" means is read from the simulator's own command record
(no heater command with a target above 0 reaches the printer) and from its reported targets.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.gcode.profiles import load_profile

from .conftest import ROOT, Daemon, Sim, at_gate, frame_ready, own_printer, wait_for

pytestmark = pytest.mark.timeout(180)

PROFILE = load_profile("ultimaker2-tpu")
#: The instruction of a job waiting at the gate (the issue's words).
INSTRUCTION = "load a fresh stretched frame, then confirm: ribbonctl frame-ready"
HEATER_CODES = ("M104", "M109", "M140", "M190")
#: How long the waiting job is watched for heat, seconds (the simulator runs 50× fast: that is
#: minutes of printer time; the bug heated 2–3 s after the first job ended).
WATCH_S = 3.0


def program(tmp_path: Path, name: str, moves: int) -> Path:
    """A plain program that heats the nozzle, prints ``moves`` short lines on the fabric, cools."""
    x0, y0, _, _ = PROFILE.frame.bounds
    lines = [f"G1 X{x0 + 10 + (i % 2) * 30} Y{y0 + 10 + i * 0.05:.2f} E0.2 F900" for i in range(moves)]
    path = tmp_path / name
    path.write_text("\n".join(["G28", "M104 S210", "M109 S210", "G90", "M83", "G0 Z0.3 F600", *lines,
                               "M104 S0"]) + "\n")
    return path


def queue(api: httpx.Client, path: Path, *, same_frame: bool = False) -> str:
    with path.open("rb") as f:
        r = api.post("/jobs", files={"gcode": (path.name, f)},
                     data={"start": "true", "same_frame": str(same_frame).lower()})
    assert r.status_code == 201, r.text
    return str(r.json()["id"])


def ribbonctl(daemon: Daemon, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.client.cli", "--url", daemon.url, *args], cwd=ROOT,
                          text=True, capture_output=True, timeout=120)


def heats(commands: list[dict[str, Any]]) -> list[str]:
    """Heater commands with a target above 0 among the simulator's executed commands."""
    out = []
    for c in commands:
        words = c["command"].split()
        if words[0].upper() in HEATER_CODES:
            target = next((float(w[1:]) for w in words[1:] if w[0].upper() == "S"), 0.0)
            if target > 0:
                out.append(c["command"])
    return out


def assert_waits_without_heat(api: httpx.Client, sim: Sim, job: str) -> None:
    """``job`` waits at the gate for WATCH_S: ready, waiting for the operator, told to load a fresh
    frame; the frame reported used with ``job`` waiting; nothing heats."""
    waiting = wait_for(api, job, "ready", timeout=60, until=at_gate, fresh_frame=False)
    before = len(sim.commands())
    assert waiting["waits_for_operator"], waiting
    assert INSTRUCTION in waiting["next"]["instruction"], waiting["next"]
    assert waiting["next"]["commands"] == ["ribbonctl frame-ready", f"ribbonctl cancel {job}"]
    frame = api.get("/printer").json()["frame"]
    assert frame["state"] == "used" and frame["waiting_job"] == job, frame
    deadline = time.monotonic() + WATCH_S
    while time.monotonic() < deadline:
        record = api.get(f"/jobs/{job}").json()
        assert at_gate(record), f"the job left the gate without a fresh frame: {record['state']} {record['stage']}"
        time.sleep(0.1)
    assert not heats(sim.commands()[before:]), "the printer was heated while the job waited for a fresh frame"
    targets = api.get("/printer", params={"refresh": "true"}).json()["heaters"]
    assert all(not (h.get("target") or 0) for h in targets.values()), targets
    transitions = [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()]
    assert "heating" not in transitions, transitions


def end_by(how: str, api: httpx.Client, sim: Sim, job: str) -> None:
    """End the first job: done, cancelled while printing, or failed on the printer (thermal
    runaway: the job is interrupted with the printer's error; the operator recovers the printer)."""
    if how == "done":
        wait_for(api, job, "done", timeout=90, fresh_frame=False)
        return
    wait_for(api, job, "printing_front", timeout=60, poll=0.02, until=lambda j: j["last_acked_line"] > 20,
             fresh_frame=False)
    if how == "cancel":
        r = api.post(f"/jobs/{job}/cancel")
        assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
        return
    sim.request({"cmd": "runaway"})
    failed = wait_for(api, job, "interrupted", timeout=60, fresh_frame=False)
    assert failed["error"], failed
    r = api.post("/printer/recover")
    assert r.status_code == 200, r.text


@pytest.mark.parametrize("how", ["done", "cancel", "failure"])
def test_the_next_job_waits_for_a_fresh_frame(how: str, api: httpx.Client, shared_sim: Sim,
                                              shared_daemon: Daemon, tmp_path: Path) -> None:
    """Two jobs queued on a fresh frame: the first prints (the frame is then used); when it ends by
    ``how`` the second waits, heaters off, until frame-ready (``ribbonctl frame-ready``, after
    ``ribbonctl status`` and ``printer`` said so); then it prints."""
    first = queue(api, program(tmp_path, "first.gcode", 300 if how == "done" else 1500))
    second = queue(api, program(tmp_path, "second.gcode", 40))
    end_by(how, api, shared_sim, first)
    assert_waits_without_heat(api, shared_sim, second)
    assert api.get("/printer").json()["frame"]["job_id"] == first
    status = ribbonctl(shared_daemon, "status", second)
    assert status.returncode == 0 and f"next: waiting for a fresh frame: {INSTRUCTION}" in status.stdout, status
    printer = ribbonctl(shared_daemon, "printer")
    assert f"frame used (job {first}); job {second} waits for a fresh frame: ribbonctl frame-ready" in printer.stdout
    confirmed = ribbonctl(shared_daemon, "frame-ready")
    assert confirmed.returncode == 0 and confirmed.stdout.startswith("frame fresh"), confirmed
    done = wait_for(api, second, "done", timeout=90, fresh_frame=False)
    assert done["error"] is None
    frame = api.get("/printer").json()["frame"]
    assert frame["state"] == "used" and frame["job_id"] == second and frame["waiting_job"] is None, frame


def test_a_job_waiting_for_its_frame_is_cancelled(api: httpx.Client, shared_sim: Sim, tmp_path: Path) -> None:
    """Cancel at the gate: cancelled at once, never heated; the next job waits in its turn."""
    first = queue(api, program(tmp_path, "first.gcode", 40))
    second = queue(api, program(tmp_path, "second.gcode", 40))
    third = queue(api, program(tmp_path, "third.gcode", 40))
    wait_for(api, first, "done", timeout=90, fresh_frame=False)
    wait_for(api, second, "ready", timeout=60, until=at_gate, fresh_frame=False)
    r = api.post(f"/jobs/{second}/cancel")
    assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
    assert "heating" not in [t["to_state"] for t in api.get(f"/jobs/{second}/transitions").json()]
    assert_waits_without_heat(api, shared_sim, third)
    assert api.post(f"/jobs/{third}/cancel").status_code == 200


def test_a_program_on_the_same_frame_needs_no_fresh_one(api: httpx.Client, shared_daemon: Daemon,
                                                        tmp_path: Path) -> None:
    """A plain program submitted with same_frame (``ribbonctl print --same-frame``) prints after
    another without frame-ready; the status says it; a design cannot say it."""
    first = queue(api, program(tmp_path, "first.gcode", 40))
    printed = ribbonctl(shared_daemon, "print", str(program(tmp_path, "second.gcode", 40)), "--same-frame",
                        "--no-wait", "--json")
    assert printed.returncode == 0, printed.stderr
    second = json.loads(printed.stdout)["id"]
    wait_for(api, first, "done", timeout=90, fresh_frame=False)
    done = wait_for(api, second, "done", timeout=90, fresh_frame=False)
    assert done["same_frame"] is True
    status = ribbonctl(shared_daemon, "status", second)
    assert "prints on the frame as it is (--same-frame" in status.stdout, status.stdout
    assert api.get("/printer").json()["frame"]["state"] == "used"
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with mesh.open("rb") as f:
        r = api.post("/jobs", files={"mesh": (mesh.name, f)}, data={"same_frame": "true"})
    assert r.status_code == 422 and "same_frame" in r.json()["detail"], r.text


def test_frame_ready_is_refused_while_a_job_holds_the_printer(api: httpx.Client, tmp_path: Path) -> None:
    """The frame under a running job is not fresh: 409 naming the job and its state."""
    job = queue(api, program(tmp_path, "long.gcode", 1500))
    wait_for(api, job, "printing_front", timeout=60, poll=0.02, until=lambda j: j["last_acked_line"] > 20,
             fresh_frame=False)
    r = api.post("/printer/frame-ready")
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    # (a plain program is named as one, not as a front: issue 36)
    assert job in detail and "printing (the program)" in detail and "not fresh" in detail, detail
    assert api.get("/printer").json()["frame"]["state"] == "used"
    assert api.get(f"/jobs/{job}").json()["state"] == "printing_front"      # the print goes on


def test_the_frame_state_survives_a_restart(tmp_path: Path) -> None:
    """At the first start nothing was confirmed: used. Confirmed fresh, a restart keeps it fresh; a
    job that printed makes it used, and a restart keeps that too: the next job waits for frame-ready."""
    with own_printer(tmp_path / "state") as (sim, daemon):
        api = daemon.client
        assert api is not None
        assert api.get("/printer").json()["frame"]["state"] == "used"
        frame_ready(api)
        api = restarted(daemon)
        assert api.get("/printer").json()["frame"]["state"] == "fresh"
        first = queue(api, program(tmp_path, "first.gcode", 40))
        wait_for(api, first, "done", timeout=90, fresh_frame=False)       # no confirmation needed: fresh
        api = restarted(daemon)
        frame = api.get("/printer").json()["frame"]
        assert frame["state"] == "used" and frame["job_id"] == first, frame
        second = queue(api, program(tmp_path, "second.gcode", 40))
        assert_waits_without_heat(api, sim, second)
        frame_ready(api)
        wait_for(api, second, "done", timeout=90, fresh_frame=False)


def restarted(daemon: Daemon) -> httpx.Client:
    daemon.stop()
    daemon.start()
    daemon.wait_printer()
    assert daemon.client is not None
    return daemon.client
