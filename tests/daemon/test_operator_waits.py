"""The operator III (issue 36 items 5, 8 and 9), end to end: a real simulator on its pty, real ribbond
processes (killed and restarted where the item is a resume), ribbonctl as a subprocess, real HTTP.

- item 9: a job that waits for a person shows what it waits for and no time left (the flip, the
  fit's review); after ``accept`` the lines shown are the back's, never the front's; a plain G-code
  job is named as a program (its stage after a resume, the refusals), never as a front;
- item 8: a head position nobody homed is shown "not homed" per axis (the API's ``homed``, ribbonctl),
  after the daemon's start and after ``recover``, which asks the printer for its position afresh;
- item 5: a job interrupted with its front printed and its frame never turned over resumes through
  the flip step (the instruction, the notice, then the alignment); one interrupted after flip-done
  resumes at the alignment, the frame checked back side up.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from .conftest import ROOT, Daemon, Sim, own_printer, submit, wait_for
from .test_daemon_e2e import operator_jogs
from .test_notify import Hook
from .test_resume import restart

pytestmark = pytest.mark.timeout(240)

MISALIGNMENT = (0.4, -0.3, 0.5)


def ctl(daemon: Daemon, *args: str) -> str:
    """``ribbonctl ARGS`` against ``daemon``: its output (exit status 0 asserted)."""
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url], cwd=ROOT,
                          text=True, capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def flip_and_measure(api: httpx.Client, sim: Sim, job: str, *, review: bool) -> httpx.Response:
    """Turn the simulated frame over with MISALIGNMENT, flip-done, report every mark's jog (the last
    with ``review``); the last answer."""
    marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
    sim.flip(*MISALIGNMENT)
    assert api.post(f"/jobs/{job}/flip-done").status_code == 200
    wait_for(api, job, "aligning", timeout=30)
    jogs = operator_jogs(marks, *MISALIGNMENT)
    for k, jog in enumerate(jogs, start=1):
        last = api.post(f"/jobs/{job}/align", json={"mark": k, "jog": list(jog), "review": review and k == len(jogs)})
        assert last.status_code == 200, last.text
    return last


# ---------------------------------------------------------------------------------- item 9


@pytest.fixture
def printer(tmp_path: Path) -> Iterator[tuple[Sim, Daemon]]:
    with own_printer(tmp_path / "state") as pair:
        yield pair


def test_a_wait_for_a_person_shows_what_it_waits_for_and_no_time_left(printer: tuple[Sim, Daemon],
                                                                       meshes: dict[str, Path]) -> None:
    sim, daemon = printer
    api = daemon.client
    assert api is not None
    job = submit(api, meshes["two_sided"], start=True)
    front = wait_for(api, job, "printing_front", timeout=90, until=lambda j: j["lines_total"])
    assert front["waiting_for"] is None and front["program"] == "front"
    flip = wait_for(api, job, "awaiting_flip", timeout=90)
    # nothing prints until the operator turns the frame over: no time left is told, the wait is named
    assert flip["waits_for_operator"] and flip["eta_s"] is None, flip
    assert flip["waiting_for"] == "the flip", flip["waiting_for"]
    text = ctl(daemon, "status", job)
    assert "waiting for the flip" in text and "ETA" not in text, text

    fit = flip_and_measure(api, sim, job, review=True)
    assert fit.json().get("review"), fit.json()
    fitted = wait_for(api, job, "fitted", timeout=30)
    assert fitted["eta_s"] is None and fitted["waiting_for"] == "your review of the fit", fitted
    accepted = api.post(f"/jobs/{job}/accept")
    assert accepted.status_code == 200, accepted.text
    back = accepted.json()
    # the job prints its back: the lines it names are the back's (none until the back's stream counts them)
    assert back["state"] == "printing_back" and back["program"] == "back", back
    assert back["lines_total"] in (None, 0) or back["lines_total"] != front["lines_total"], back
    assert "front: line" not in ctl(daemon, "status", job)
    printing = wait_for(api, job, "printing_back", timeout=30, until=lambda j: j["last_acked_line"] > 0)
    assert printing["program"] == "back" and printing["eta_s"] is not None and printing["waiting_for"] is None
    wait_for(api, job, "done", timeout=120)


def plain_program(path: Path, moves: int = 400) -> Path:
    """A plain program of ``moves`` 100 mm travels above the fabric (about 80 s on the simulator)."""
    lines = ["G28", "G90", "G0 Z5 F600"]
    lines += [f"G0 X{60 + 100 * (k % 2)} Y{60 + 100 * ((k // 2) % 2)} F600" for k in range(moves)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_plain_program_is_named_a_program_not_a_front(printer: tuple[Sim, Daemon], tmp_path: Path) -> None:
    sim, daemon = printer
    api = daemon.client
    assert api is not None
    with plain_program(tmp_path / "travels.gcode").open("rb") as f:
        r = api.post("/jobs", files={"gcode": ("travels.gcode", f)}, data={"start": "true"})
    assert r.status_code == 201, r.text
    job = r.json()["id"]
    wait_for(api, job, "printing_front", timeout=60, until=lambda j: j["last_acked_line"] > 10)
    assert api.post(f"/jobs/{job}/pause").status_code == 200
    paused = wait_for(api, job, "paused", timeout=60, until=lambda j: j["stage"] == "paused (head parked)")
    assert paused["eta_s"] is None and paused["waiting_for"] == "resume", paused
    assert api.post(f"/jobs/{job}/resume").status_code == 200
    resumed = wait_for(api, job, "printing_front", timeout=60)
    assert resumed["stage"] == "printing the program", resumed["stage"]
    text = ctl(daemon, "status", job)
    assert "front" not in text and "printing " in text and "program: line" in text, text
    refused = api.post(f"/jobs/{job}/flip-done")
    assert refused.status_code == 409
    assert "the job is printing (the program)" in refused.json()["detail"], refused.json()
    assert "printing_front" not in refused.json()["detail"]
    manual = api.post("/printer/jog", json={"dx": 1, "dy": 0})
    assert manual.status_code == 409 and "printing (the program)" in manual.json()["detail"], manual.text
    assert api.post(f"/jobs/{job}/cancel").status_code == 200


# ---------------------------------------------------------------------------------- item 8


def test_an_unhomed_head_is_shown_not_homed_and_recover_asks_afresh(printer: tuple[Sim, Daemon]) -> None:
    sim, daemon = printer
    api = daemon.client
    assert api is not None
    # just connected: nothing homed the printer (the firmware's M114 says 0 0 0, which means nothing)
    status = api.get("/printer", params={"refresh": "true"}).json()
    assert status["homed"] == [], status
    text = ctl(daemon, "printer")
    assert "x not homed y not homed z not homed" in text and "x 0.00" not in text, text
    # the console refuses a move for the same reason the position is shown so
    refused = api.post("/printer/gcode", json={"commands": ["G0 X50 F600"]})
    assert refused.status_code == 422 and "position is not known" in refused.text, refused.text
    home = api.post("/printer/home", timeout=330)
    assert home.status_code == 200 and home.json()["homed"] == ["x", "y", "z"], home.text
    assert "not homed" not in ctl(daemon, "printer")
    # a program's motors-off (M84) leaves the axes not homed (Marlin asks to home again)
    api.post("/printer/gcode", json={"commands": ["M84 Z"]})
    assert api.get("/printer").json()["homed"] == ["x", "y"]
    assert "z not homed" in ctl(daemon, "printer")

    assert api.post("/printer/emergency-stop").status_code == 200
    before = len(sim.commands())
    recovered = api.post("/printer/recover", timeout=60)
    assert recovered.status_code == 200, recovered.text
    after = [c["command"].split()[0] for c in sim.commands()[before:]]
    # the firmware restarted: nothing is homed, and the position shown is the one it reports now
    assert recovered.json()["homed"] == [], recovered.json()
    assert "M114" in after and recovered.json()["position"] is not None, (after, recovered.json())
    assert "x not homed y not homed z not homed" in ctl(daemon, "printer")


# ---------------------------------------------------------------------------------- item 5


def wait_notice(hook: Hook, title: str, after: float, timeout: float = 10.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while True:
        found = [body for t, body in hook.got if t >= after and body["title"].startswith(title)]
        if found:
            return found[0]
        assert time.monotonic() < deadline, [body["title"] for _, body in hook.got]
        time.sleep(0.05)


def test_a_resume_after_the_front_goes_through_the_flip(tmp_path: Path, meshes: dict[str, Path]) -> None:
    hook = Hook()
    extra = f'[notify]\nurls = ["{hook.url}"]\ntimeout_s = 2\n'
    try:
        with own_printer(tmp_path / "state", extra=extra) as (sim, daemon):
            api = daemon.client
            assert api is not None
            job = submit(api, meshes["two_sided"], start=True)
            wait_for(api, job, "awaiting_flip", timeout=120)
            daemon.kill()                                   # the front printed, the frame not turned over

            api = restart(daemon, sim)
            assert api.get(f"/jobs/{job}").json()["state"] == "interrupted"
            resumed_at = time.time()
            r = api.post(f"/jobs/{job}/resume")
            assert r.status_code == 200, r.text
            assert "back side up" not in r.json()["next"]["instruction"], r.json()["next"]
            # the flip step, as after a front printed in one go: its instruction and its notice
            flip = wait_for(api, job, "awaiting_flip", timeout=60)
            assert "Turn the frame over" in flip["next"]["instruction"], flip["next"]
            assert flip["next"]["commands"][0] == f"ribbonctl flip-done {job}"
            notice = wait_notice(hook, "Flip the frame", resumed_at)
            assert f"ribbonctl flip-done {job}" in notice["message"], notice
            states = [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()]
            assert states[-3:] == ["interrupted", "awaiting_check", "awaiting_flip"], states

            # flip-done given, then interrupted while aligning: the frame is back side up, no flip again
            sim.flip(*MISALIGNMENT)
            assert api.post(f"/jobs/{job}/flip-done").status_code == 200
            wait_for(api, job, "aligning", timeout=30, until=lambda j: j["waits_for_operator"])
            daemon.kill()
            api = restart(daemon, sim)
            r = api.post(f"/jobs/{job}/resume")
            assert r.status_code == 200, r.text
            check = wait_for(api, job, "awaiting_check", timeout=60, until=lambda j: j["waits_for_operator"])
            assert "back side up" in check["next"]["instruction"], check["next"]
            assert api.post(f"/jobs/{job}/frame-ok").status_code == 200
            wait_for(api, job, "aligning", timeout=60, until=lambda j: j["waits_for_operator"])
            marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
            for k, jog in enumerate(operator_jogs(marks, *MISALIGNMENT), start=1):
                assert api.post(f"/jobs/{job}/align", json={"mark": k, "jog": list(jog)}).status_code == 200
            wait_for(api, job, "done", timeout=150)
            states = [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()]
            assert states.count("awaiting_flip") == 2, states          # never asked to turn it over a third time
    finally:
        hook.close()
