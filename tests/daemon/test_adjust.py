"""Adjusting a print in progress (issue 36, item 10), end to end: a real daemon streams a plain
G-code job to the simulator over its pty while the feed override (M220), the flow (M221), the heater
targets and the queries (M105, M114) go in beside it through the console's checker; everything
else (a move, a wait, a value outside the profile's limits) is refused while it prints, and nothing
of it reaches the printer.

Expectations from the protocol and the profile: the simulator runs a move at F × M220/100 and pushes
E × M221/100 of filament (Marlin's semantics), so the deposited segments show where the adjustment
reached the firmware; the program's lines run each once, in order, with the adjustments between them.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from ribbond.gcode.profiles import load_profile
from tests.daemon.conftest import ROOT, HOST_COMMANDS, Daemon, Sim, wait_for

PROFILE = load_profile("ultimaker2-tpu")           # the daemon's default profile
X0, Y0, X1, Y1 = PROFILE.frame.bounds
FEED = 900.0                                        # mm/min: the paper's 15 mm/s
E_PER_MOVE = 1.0
MOVES = 160
SPEED, FLOW = 50.0, 110.0                            # within the profile's [adjust]
INJECTED = ("M220", "M221", "M104", "M140")


def zigzag(path: Path, moves: int = MOVES) -> list[str]:
    """A zigzag of ``moves`` extruding moves of 40 mm at FEED on the fabric (MOVES: ~7 s on the
    simulator), written to ``path``; its lines."""
    lines = ["G28", "G90", "M83", "G0 Z5 F600", f"G0 X{X0 + 10:g} Y{Y0 + 10:g} F3000", "G0 Z0.2 F600"]
    for i in range(moves):
        x = X0 + 10 + (40 if i % 2 == 0 else 0)
        y = Y0 + 10 + (Y1 - Y0 - 20) * (i + 1) / moves
        lines.append(f"G1 X{x:g} Y{y:g} E{E_PER_MOVE:g} F{FEED:g}")
    lines += ["G0 Z5 F600", "M400"]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return lines


def start_program(api: httpx.Client, program: Path) -> str:
    with program.open("rb") as handle:
        r = api.post("/jobs", files={"gcode": (program.name, handle)}, data={"start": "true"})
    assert r.status_code == 201, r.text
    return str(r.json()["id"])


def wait_moving(api: httpx.Client, sim: Sim, job: str, since: int, moves: int = 12) -> None:
    """Until ``job`` prints and the simulator has run ``moves`` extruding moves after its ``since``-th command."""
    wait_for(api, job, "printing_front", timeout=60, poll=0.02)
    deadline = time.monotonic() + 30
    while sum(c["command"].startswith("G1 ") for c in sim.commands()[since:]) < moves:
        assert time.monotonic() < deadline, "the program did not start moving"
        time.sleep(0.02)


def _segments_after(api: httpx.Client, sim: Sim, job: str) -> list[dict]:
    """The job's deposited segments, once it is done."""
    wait_for(api, job, "done", timeout=120)
    return sim.segments()


REFUSED_WHILE_PRINTING = [
    # refused because a program prints (409, allowed once paused), or beyond the profile (422)
    (["G1 X100 Y100"], 409, "G1 (it moves the head) is not accepted while a program prints"),
    (["M105", "G28"], 409, "command 2 (G28)"),
    (["M220 S500"], 422, "feed override above 100 %"),
    (["M220 S5"], 422, "feed override below 25 %"),
    (["M221 S200"], 422, "flow above 120 %"),
    ([f"M104 S{PROFILE.temperatures.nozzle_max + 140:g}"], 422, "nozzle_max"),
    (["M104 S0"], 409, "adjust.nozzle_min"),
    (["M109 S220"], 409, "M109 is not accepted while a program prints"),
    (["M400"], 409, "M400 is not accepted while a program prints"),
    (["M140 S400"], 422, "bed_max"),
]


def test_a_print_is_adjusted_beside_its_program_and_only_so(shared_daemon: Daemon, shared_sim: Sim,
                                                            api: httpx.Client, tmp_path: Path) -> None:
    program = zigzag(tmp_path / "zigzag.gcode")
    since = len(shared_sim.commands())
    job = start_program(api, tmp_path / "zigzag.gcode")
    wait_moving(api, shared_sim, job, since)
    before = shared_sim.commands()

    # refused while printing: named, and nothing of the batch reaches the printer
    for commands, status, words in REFUSED_WHILE_PRINTING:
        r = api.post("/printer/gcode", json={"commands": commands})
        assert r.status_code == status and words in r.json()["detail"], (commands, r.text)
    for body, status, words in (({"speed": 500}, 422, "feed override above 100 %"),
                                ({"nozzle": 20}, 409, "adjust.nozzle_min"), ({"flow": 50}, 422, "flow below 80 %"),
                                ({}, 422, ""), ({"speed": None}, 422, "null is not a value"),
                                ({"bed": False}, 422, "")):
        r = api.post("/printer/adjust", json=body)
        assert r.status_code == status and words in r.text, (body, r.text)
    for route, body in (("/printer/jog", {"dx": 1, "dy": 0}), ("/printer/home", None)):
        assert api.post(route, json=body).status_code == 409
    sent = [c["command"] for c in shared_sim.commands()[len(before):]]
    assert not [c for c in sent if c.split()[0] in INJECTED + ("G28", "M109", "M400") and c != "M400"
                or c in ("G1 X100 Y100", "M220 S500", "M104 S0")], sent

    # the queries at any time
    r = api.post("/printer/gcode", json={"commands": ["M105", "M114"]})
    assert r.status_code == 200, r.text
    answers = r.json()["answers"]
    assert r.json()["printing"] == job and any("T:" in line for line in answers[0]["answer"])
    assert any(line.startswith("X:") for line in answers[1]["answer"]), answers

    # the adjustment, read back from the printer
    r = api.post("/printer/adjust", json={"speed": SPEED, "flow": FLOW})
    assert r.status_code == 200, r.text
    printer = r.json()["printer"]
    assert (printer["speed_percent"], printer["flow_percent"]) == (SPEED, FLOW), printer
    assert api.get(f"/jobs/{job}").json()["state"] == "printing_front"

    # the CLI: the nozzle target within the limits, a refusal exits 2 naming it
    cli = [sys.executable, "-m", "ribbond.client.cli", "adjust", "--url", shared_daemon.url]
    ok = subprocess.run(cli + ["--nozzle", f"{PROFILE.temperatures.nozzle:g}"], cwd=ROOT, text=True,
                        capture_output=True, timeout=60)
    assert ok.returncode == 0 and f"beside job {job}'s program" in ok.stdout, (ok.stdout, ok.stderr)
    assert "speed 50 %" in ok.stdout and "flow 110 %" in ok.stdout, ok.stdout
    bad = subprocess.run(cli + ["--speed", "500"], cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert bad.returncode == 2 and "feed override above 100 %" in bad.stderr, (bad.stdout, bad.stderr)

    segments = _segments_after(api, shared_sim, job)
    done = api.get(f"/jobs/{job}").json()
    assert done["state"] == "done", done

    # every program line ran once, in order; the adjustments went in between them
    executed = [c["command"] for c in shared_sim.commands()[len(before):]]
    ran = [c for c in shared_sim.commands() if c["command"].split()[0] not in HOST_COMMANDS + INJECTED]
    program_ran = [c["command"] for c in ran]
    start = len(program_ran) - program_ran[::-1].index("G28") - 1
    assert program_ran[start:start + len(program)] == program, program_ran[start:]
    assert f"M220 S{SPEED:g}" in executed and f"M221 S{FLOW:g}" in executed
    assert f"M104 S{PROFILE.temperatures.nozzle:g}" in executed

    # the firmware ran the moves after the adjustment at F × 50 % and pushed E × 110 %
    deposits = segments[-MOVES:]
    feeds = [s["feed"] for s in deposits]
    flows = [s["e"] / E_PER_MOVE for s in deposits]
    assert set(feeds) == {FEED, FEED * SPEED / 100}, sorted(set(feeds))
    assert all(f == pytest.approx(1.0) or f == pytest.approx(FLOW / 100) for f in flows), flows
    switch_feed = feeds.index(FEED * SPEED / 100)
    switch_flow = next(i for i, f in enumerate(flows) if f == pytest.approx(FLOW / 100))
    assert all(f == FEED for f in feeds[:switch_feed]) and all(f == FEED * SPEED / 100 for f in feeds[switch_feed:])
    assert all(f == pytest.approx(1.0) for f in flows[:switch_flow])
    assert all(f == pytest.approx(FLOW / 100) for f in flows[switch_flow:])
    assert 10 < switch_feed <= switch_flow < MOVES, (switch_feed, switch_flow)

    # back to the program as written, between prints: the same route
    r = api.post("/printer/adjust", json={"speed": 100, "flow": 100})
    assert r.status_code == 200 and r.json().get("printing") is None, r.text
    assert (r.json()["printer"]["speed_percent"], r.json()["printer"]["flow_percent"]) == (100, 100)
