"""Every limit on every route (issue 22, items 8 and 11): a table of route × axis × below/above
the profile's bound, each refused naming the limit with nothing sent to the printer and nothing
kept; a slicer's file with its fast Z lifts accepted, its feed rates clamped as the firmware would
(the job's notes say so, the simulator executes the clamped feeds), and an unsafe one still refused
with the line named; the request body limit exact for a chunked body. Expected values from the
profile (frame, fabric, temperatures, speeds) and the daemon's configured upload limit."""

from __future__ import annotations

import asyncio
import subprocess
import sys
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.api.guard import Guard, HostRule, Policy
from ribbond.printer.link import prepare_program
from tests.daemon.conftest import ROOT, Daemon, Sim, wait_for
from tests.daemon.test_console import (BED_MAX, CX, CY, FABRIC, NOZZLE_MAX, PROFILE, SAFE_Z, X0, X1, Y0, Y1,  # noqa: F401
                                       at_centre)  # the profile's limits and the fixture, shared
from tests.daemon.test_programs import SLICER
from tests.gcode.reader import read_gcode

MO = PROFILE.motion
LIMITS = {"X": MO.max_xy_speed, "Y": MO.max_xy_speed, "Z": MO.max_z_speed, "E": MO.max_e_speed}
FRAME = f"outside the frame (x {X0:g} to {X1:g}, y {Y0:g} to {Y1:g} mm)"
INTO_FABRIC = f"below the fabric (z {FABRIC:g} mm)"

#: (axis, side) -> the value past the bound: a coordinate (mm), or a temperature (°C)
PAST = {("X", "below"): X0 - 1, ("X", "above"): X1 + 1, ("Y", "below"): Y0 - 1, ("Y", "above"): Y1 + 1,
        ("Z", "below"): FABRIC - 0.5, ("nozzle", "below"): -1.0, ("nozzle", "above"): NOZZLE_MAX + 1,
        ("bed", "below"): -1.0, ("bed", "above"): BED_MAX + 1}
REASON = {"X": FRAME, "Y": FRAME, "Z": INTO_FABRIC, "nozzle": "nozzle", "bed": "bed"}
HEATER = {"nozzle": "M104", "bed": "M140"}


def _jog(axis: str, value: float) -> tuple[str, dict[str, Any]]:
    here = {"X": CX, "Y": CY, "Z": SAFE_Z}[axis]          # from the centre at the safe height
    d = {"dx": 0.0, "dy": 0.0, "dz": 0.0}
    d[f"d{axis.lower()}"] = value - here
    return "/printer/jog", d


def _goto(axis: str, value: float) -> tuple[str, dict[str, Any]]:
    return "/printer/goto", {"x": value if axis == "X" else CX, "y": value if axis == "Y" else CY}


def _gcode(axis: str, value: float) -> tuple[str, dict[str, Any]]:
    command = f"{HEATER[axis]} S{value:g}" if axis in HEATER else f"G1 {axis}{value:g} F600"
    return "/printer/gcode", {"commands": [command]}


def _heat(axis: str, value: float) -> tuple[str, dict[str, Any]]:
    return "/printer/heat", {axis: value}


def _job(axis: str, value: float) -> tuple[str, dict[str, Any]]:
    line = f"{HEATER[axis]} S{value:g}" if axis in HEATER else f"G1 {axis}{value:g} F600"
    return "/jobs", {"program": f"G28\nG90\nG1 Z{SAFE_Z:g} F600\nG1 X{CX:g} Y{CY:g} F3000\n{line}\n"}


ROUTES = {"jog": (_jog, "XYZ"), "goto": (_goto, "XY"), "gcode": (_gcode, ["X", "Y", "Z", "nozzle", "bed"]),
          "heat": (_heat, ["nozzle", "bed"]), "job": (_job, ["X", "Y", "Z", "nozzle", "bed"])}
TABLE = [(route, axis, side) for route, (_, axes) in ROUTES.items() for axis in axes
         for side in ("below", "above") if (axis, side) in PAST]


@pytest.mark.parametrize("route, axis, side", TABLE, ids=[f"{r}-{a}-{s}" for r, a, s in TABLE])
def test_every_limit_on_every_route(at_centre: httpx.Client, shared_sim: Sim, tmp_path: Path,
                                    route: str, axis: str, side: str) -> None:
    path, body = ROUTES[route][0](axis, PAST[axis, side])
    before, jobs = shared_sim.program_commands(), at_centre.get("/jobs").json()
    if route == "job":
        r = at_centre.post("/jobs", files={"gcode": ("past.gcode", body["program"].encode())},
                           data={"start": "true"})
    else:
        r = at_centre.post(path, json=body)
    assert r.status_code == 422, r.text
    detail = str(r.json()["detail"])
    if route == "heat" and side == "below":
        assert "greater than or equal to 0" in detail, detail        # the request model's bound
    else:
        assert REASON[axis] in detail, detail
        if axis in HEATER and side == "above":
            assert f"{axis}_max ({PAST[axis, side] - 1:g} °C)" in detail, detail
    if route == "job":
        assert "past.gcode, line 5:" in detail, detail
    assert shared_sim.program_commands() == before                    # nothing reached the printer
    assert at_centre.get("/jobs").json() == jobs                      # nothing kept
    assert at_centre.get("/printer").json()["head"] == pytest.approx([CX, CY, SAFE_Z])


def test_a_slicers_file_is_clamped_where_firmware_would_clamp(api: httpx.Client, shared_sim: Sim,
                                                              shared_daemon: Daemon) -> None:
    """PrusaSlicer/Cura-style start (G28, G1 Z15.0 F6000, M104, M109, G92 E0) and moves: accepted,
    the notes say how many feed rates were clamped, the simulator executes the clamped feeds."""
    r = api.post("/jobs", files={"gcode": ("slicer.gcode", SLICER.encode())}, data={"start": "true"})
    assert r.status_code == 201, r.text
    job = r.json()
    assert job["notes"] and job["notes"][0].startswith(
        f"6 moves' feed rates clamped to the profile (E ≤ {MO.max_e_speed:g} mm/s, Z ≤ {MO.max_z_speed:g} mm/s)")
    before = len(shared_sim.commands())
    wait_for(api, job["id"], "done", timeout=90)
    stored = api.get(f"/jobs/{job['id']}/files/program.gcode").text
    assert f"G1 Z15.0 F{MO.max_z_speed * 60:g}" in stored
    ran = [c["command"] for c in shared_sim.commands()[before:]
           if c["command"].split()[0] not in ("M105", "M114", "M155")]
    program = prepare_program(stored.splitlines())
    at = ran.index(program[0])
    assert ran[at:at + len(program)] == program                      # the stored, clamped program ran
    executed = read_gcode("\n".join(ran[at:at + len(program)]))
    assert len(executed.moves) == len(read_gcode(SLICER).moves)
    for move in executed.moves:
        for axis, speed in move.axis_speeds().items():
            assert speed <= LIMITS[axis] + 1e-3, (move, axis, speed)
    # ribbonctl status shows the notes
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "status", job["id"], "--url", shared_daemon.url],
                          cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert proc.returncode == 0 and "note: 6 moves' feed rates clamped" in proc.stdout, (proc.stdout, proc.stderr)


def test_an_unsafe_slicer_file_is_still_refused_with_the_line_named(api: httpx.Client) -> None:
    lines = SLICER.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("G1 Z0.3")) + 1
    bad = "\n".join(lines[:at] + ["G1 Z-0.2 ; into the fabric"] + lines[at:]) + "\n"
    jobs = api.get("/jobs").json()
    r = api.post("/jobs", files={"gcode": ("slicer-bad.gcode", bad.encode())}, data={"start": "true"})
    assert r.status_code == 422, r.text
    assert r.json()["detail"].startswith(f"slicer-bad.gcode, line {at + 1}: the move goes down to z -0.2, "
                                         f"{INTO_FABRIC}"), r.text
    assert api.get("/jobs").json() == jobs


# ------------------------------------------------------------------------------- the body limit


async def _post_chunked(limit: int, size: int) -> tuple[int, int]:
    """Through the gate (``Guard``, limit ``limit`` bytes): a body of ``size`` bytes in chunks of
    1000 without a Content-Length. The status answered and the bytes the application read."""
    read = 0

    async def app(scope: Any, receive: Any, send: Any) -> None:
        nonlocal read
        while True:
            message = await receive()
            read += len(message.get("body", b""))
            if not message.get("more_body"):
                break
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"ok"})

    chunks = [b"x" * min(1000, size - i) for i in range(0, size, 1000)]

    async def receive() -> dict[str, Any]:
        body = chunks.pop(0)
        return {"type": "http.request", "body": body, "more_body": bool(chunks)}

    sent: list[dict[str, Any]] = []

    async def send(message: dict[str, Any]) -> None:
        sent.append(message)

    scope = {"type": "http", "method": "POST", "path": "/jobs", "headers": [(b"host", b"127.0.0.1:7125")],
             "server": ("127.0.0.1", 7125)}
    await Guard(app, Policy(None, HostRule("127.0.0.1"), limit))(scope, receive, send)
    return sent[0]["status"], read


@pytest.mark.parametrize("size, status", [(10_000, 200), (10_001, 413), (15_000, 413), (20_001, 413)])
def test_a_chunked_body_just_over_the_limit_is_refused(size: int, status: int) -> None:
    got, read = asyncio.run(_post_chunked(10_000, size))
    assert got == status
    if status == 413:
        assert read <= 10_000                    # the application never saw the body past the limit
