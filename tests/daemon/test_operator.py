"""The operator around a print (issue 13), end to end: a real simulator on its pty, real ribbond
processes, real HTTP. Safe stops (SIGTERM mid-print), the idle-heater policy while paused, manual
control, the jog-driven alignment, reprints and deletion, plain G-code jobs, the API's progress.

Expectations come from the protocol: what the simulator executed (its command record, replayed
with Marlin's semantics for the heater targets and the nozzle's height) and the programs' own
commands; never from an earlier run.
"""

from __future__ import annotations

import math
import signal
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.gcode.profiles import load_profile
from ribbond.printer.link import prepare_program

from .conftest import CENTER, HOST_COMMANDS, Daemon, Sim, own_printer, submit, wait_for

pytestmark = pytest.mark.timeout(180)

PROFILE = load_profile("ultimaker2-tpu")
#: The frame put back after the flip: dx, dy (mm), rotation (degrees).
MISALIGNMENT = (0.5, -0.3, 0.7)


def replay(commands: list[str]) -> dict[str, Any]:
    """Marlin's state after ``commands`` (as executed): heater targets and the nozzle's z."""
    state: dict[str, Any] = {"nozzle": 0.0, "bed": 0.0, "z": None, "relative": False}
    for command in commands:
        words = command.split()
        code = words[0].upper()
        args = {w[0].upper(): w[1:] for w in words[1:]}
        if code == "G90":
            state["relative"] = False
        elif code == "G91":
            state["relative"] = True
        elif code == "G28":
            state["z"] = 0.0
        elif code in ("G0", "G1") and "Z" in args:
            z = float(args["Z"])
            state["z"] = (state["z"] or 0.0) + z if state["relative"] else z
        elif code in ("M104", "M109") and "S" in args:
            state["nozzle"] = float(args["S"])
        elif code in ("M140", "M190") and "S" in args:
            state["bed"] = float(args["S"])
    return state


def executed(sim: Sim, since: int = 0) -> list[str]:
    return [c["command"] for c in sim.commands()[since:]]


def wait_until(what: str, check: Any, timeout: float = 60.0, poll: float = 0.05) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {timeout:.0f} s")
        time.sleep(poll)


# ---------------------------------------------------------------------------------- own daemon


@pytest.mark.timeout(240)
def test_pause_heaters_manual_control_and_a_safe_stop_on_sigterm(tmp_path: Path, meshes: dict[str, Path]) -> None:
    """Paused: the heaters follow [flip] (lowered), go off after off_after_s, the operator may jog
    and type G-code, resume reheats. SIGTERM mid-print: no program line after the stop, heaters off,
    the nozzle lifted by the park lift; the job interrupted with the exact checkpoint; started again
    it is a new run that prints to the end."""
    idle = '[flip]\nheaters = "lower"\nlower_to = 150\noff_after_s = 1\n'
    with own_printer(tmp_path / "state", extra=idle) as (sim, daemon):
        api = daemon.client
        assert api is not None
        job = submit(api, meshes["one_sided"], start=True)
        wait_for(api, job, "printing_front", timeout=90, poll=0.02, until=lambda j: j["last_acked_line"] > 20)

        # manual control is refused while the program streams, naming what to do instead
        r = api.post("/printer/jog", json={"dx": 1, "dy": 0})
        assert r.status_code == 409 and "pause it first" in r.json()["detail"], r.text
        # typed G-code goes in beside the program only as a query or an adjustment (issue 36)
        assert api.post("/printer/gcode", json={"commands": ["M105"]}).status_code == 200
        r = api.post("/printer/gcode", json={"commands": ["G1 X120"]})
        assert r.status_code == 409 and "not accepted while a program prints" in r.json()["detail"], r.text

        r = api.post(f"/jobs/{job}/pause")
        assert r.status_code == 200 and r.json()["state"] == "paused", r.text
        paused = wait_until("heaters off while paused",
                            lambda: (j := api.get(f"/jobs/{job}").json())["stage"].startswith("heaters off") and j)
        assert paused["state"] == "paused" and paused["waits_for_operator"]
        assert f"ribbonctl resume {job}" in paused["next"]["instruction"]
        after_pause = executed(sim)
        lowered = len(after_pause) - 1 - after_pause[::-1].index("M104 S150")
        assert "M104 S0" in after_pause[lowered:] and "M140 S0" in after_pause[lowered:]
        assert replay(after_pause)["nozzle"] == 0.0

        # paused: the head can be moved and G-code typed; the answers come back
        head = api.get("/printer").json()["head"]
        r = api.post("/printer/jog", json={"dx": 5.0, "dy": -5.0})
        assert r.status_code == 200, r.text
        assert r.json()["position"] == pytest.approx([head[0] + 5, head[1] - 5, head[2]])
        r = api.post("/printer/jog", json={"dx": -500.0, "dy": 0.0})
        assert r.status_code == 422 and "outside the frame" in r.json()["detail"]
        answers = api.post("/printer/gcode", json={"commands": ["M105", "M114"]}).json()["answers"]
        assert [a["command"] for a in answers] == ["M105", "M114"]
        assert any("T:" in line for line in answers[0]["answer"])
        assert any(line.startswith("X:") for line in answers[1]["answer"])
        assert api.post("/printer/gcode", json={"commands": ["M112"]}).status_code == 422

        before_resume = len(sim.commands())
        r = api.post(f"/jobs/{job}/resume")
        assert r.status_code == 200 and r.json()["state"] == "printing_front", r.text
        resumed = executed(sim, before_resume)
        nozzle = PROFILE.temperatures.nozzle
        assert resumed[:2] == [f"M104 S{nozzle:.0f}", f"M109 S{nozzle:.0f}"], resumed[:4]

        # SIGTERM mid-print, as systemctl stop does
        record = wait_for(api, job, "printing_front", timeout=30, poll=0.02,
                          until=lambda j: j["last_acked_line"] > paused["checkpoint_line"] + 20)
        assert record["last_acked_line"] < record["lines_total"] - 200, "too late to test the stop"
        assert daemon.proc is not None
        daemon.proc.send_signal(signal.SIGTERM)
        assert daemon.proc.wait(40) == 0
        daemon.proc = None
        commands = executed(sim)
        safe = ["M104 S0", "M140 S0", "M107", "G91", f"G0 Z{PROFILE.park_lift:.3f} F{PROFILE.motion.z_speed * 60:.0f}",
                "G90", "M400", "M84"]
        at = next(i for i in range(before_resume, len(commands)) if commands[i:i + len(safe)] == safe)
        assert commands[at + len(safe):] == [], "commands after the safe stop"
        end, before_stop = replay(commands), replay(commands[:at])
        assert end["nozzle"] == 0.0 and end["bed"] == 0.0
        assert end["z"] == pytest.approx(before_stop["z"] + PROFILE.park_lift)
        assert end["z"] >= PROFILE.layers.fabric_z + PROFILE.park_lift

        daemon.start()
        api = daemon.client
        assert api is not None
        stopped = api.get(f"/jobs/{job}").json()
        assert stopped["state"] == "interrupted" and "SIGTERM" in stopped["error"]
        assert stopped["checkpoint"] == "front_stopped"
        # exact: the program lines executed after the resume are the program from the pause point
        # to the checkpoint line, and nothing after it
        assert paused["checkpoint"] == "front_paused"
        line, p = stopped["checkpoint_line"], paused["checkpoint_line"]
        front = prepare_program(Path(record["design_dir"], "front.gcode").read_text().splitlines())
        streamed = [c for c in commands[before_resume:at] if c.split()[0] not in HOST_COMMANDS]
        # (counted as the link counts them: lines acknowledged, so front[:line] ran)
        assert p < line < len(front)
        assert streamed[len(streamed) - (line - p):] == front[p:line]
        assert stopped["last_acked_line"] == line
        assert stopped["next"]["commands"] == [f"ribbonctl resume {job}", f"ribbonctl start {job}",
                                               f"ribbonctl cancel {job}", f"ribbonctl delete {job}"]

        # a new run of the same design
        daemon.wait_printer()
        r = api.post(f"/jobs/{job}/start")
        assert r.status_code == 200 and r.json()["state"] == "ready", r.text
        done = wait_for(api, job, "done", timeout=90)
        assert done["progress"] == 1.0 and done["eta_s"] == 0.0
        assert [run["state"] for run in done["runs"]] == ["interrupted"]
        assert done["runs"][0]["checkpoint"] == "front_stopped" and done["runs"][0]["last_acked_line"] == line
        states = [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()]
        assert states[-5:] == ["interrupted", "ready", "heating", "printing_front", "done"]

        # a fatal error of the print task (the board resets mid-print): interrupted, not failed,
        # and the job can be printed again
        assert api.post(f"/jobs/{job}/start").status_code == 200
        wait_for(api, job, "printing_front", timeout=60, poll=0.02, until=lambda j: j["last_acked_line"] > 50)
        sim.request({"cmd": "reset"})
        broken = wait_for(api, job, "interrupted", timeout=60)
        assert broken["error"].startswith("printer: ") and "reset" in broken["error"], broken["error"]
        assert f"ribbonctl start {job}" in broken["next"]["commands"]
        assert len(broken["runs"]) == 2

        # no job, heaters the operator turned on: off before the daemon exits
        daemon.wait_printer()
        assert api.post("/printer/heat", json={"nozzle": 80}).status_code == 200
        assert replay(executed(sim))["nozzle"] == 80.0
        daemon.stop()
        assert replay(executed(sim))["nozzle"] == 0.0 and replay(executed(sim))["bed"] == 0.0


def test_a_stop_while_heating_ends_the_heater_wait(tmp_path: Path) -> None:
    """SIGTERM while the firmware waits for the bed (M190 holds its queue, M109 is in flight
    behind it): M108 ends the waits, so the safe stop runs at once, without the emergency stop."""
    with own_printer(tmp_path / "state") as (sim, daemon):
        api = daemon.client
        assert api is not None
        x0, y0, _, _ = PROFILE.frame.bounds
        program = tmp_path / "hot.gcode"
        program.write_text(f"G28\nM140 S100\nM104 S200\nM190 S100\nM109 S200\nG90\nG0 Z5 F600\n"
                           f"G0 X{x0 + 5} Y{y0 + 5} F3000\nG1 X{x0 + 25} Y{y0 + 5} E1 F900\nM104 S0\nM140 S0\n")
        with program.open("rb") as f:
            job = api.post("/jobs", files={"gcode": ("hot.gcode", f)}, data={"start": "true"}).json()["id"]
        wait_for(api, job, "heating", timeout=30, poll=0.02)
        wait_until("the bed wait running", lambda: "M190 S100" in executed(sim), poll=0.01)
        # the link sends ahead at its own pace: stop only once M109 is in the firmware's queue
        wait_until("M109 queued behind the bed wait", lambda: "M109 S200" in sim.queued(), poll=0.01)
        assert daemon.proc is not None
        daemon.proc.send_signal(signal.SIGTERM)
        assert daemon.proc.wait(40) == 0
        daemon.proc = None
        commands = executed(sim)
        after = commands[commands.index("M190 S100"):]
        assert "M108" in after and "M112" not in commands
        # M108 goes on while lines in flight still hold waits: one reaches M109's too
        assert any(c == "M108" for c in after[after.index("M109 S200"):]), after
        assert replay(commands)["nozzle"] == 0.0 and replay(commands)["bed"] == 0.0
        assert f"G0 Z{PROFILE.park_lift:.3f} F{PROFILE.motion.z_speed * 60:.0f}" in commands
        daemon.start()
        assert daemon.client is not None
        record = daemon.client.get(f"/jobs/{job}").json()
        assert record["state"] == "interrupted" and "SIGTERM" in record["error"]


def test_a_job_started_while_the_printer_is_away_waits_for_it(tmp_path: Path, meshes: dict[str, Path]) -> None:
    """No printer: a started job stays ready, queued, saying it waits for the printer (it does not
    fail); deleting it removes its files; the state directory keeps nothing of it. A compile the
    daemon's stop interrupted is made again when the job is started."""
    daemon = Daemon(tmp_path / "state", str(tmp_path / "no-printer"), cache=False)   # a compile to stop
    try:
        daemon.start()
        api = daemon.client
        assert api is not None
        design = submit(api, meshes["one_sided"], start=True)
        wait_for(api, design, "compiling", timeout=30, poll=0.02)
        daemon.stop()                                             # SIGTERM during the compile
        daemon.start()
        api = daemon.client
        assert api is not None
        assert api.get(f"/jobs/{design}").json()["state"] == "interrupted"
        r = api.post(f"/jobs/{design}/start")
        assert r.status_code == 200 and r.json()["state"] == "submitted", r.text
        ready = wait_for(api, design, "ready", timeout=90, until=lambda j: j["stage"] == "waiting for the printer")
        assert ready["estimate_s"]["front"] > 0 and ready["eta_s"] > 0
        assert api.delete(f"/jobs/{design}").status_code == 204

        program = tmp_path / "line.gcode"
        program.write_text("G28\nG90\nG0 Z5 F600\nG0 X50 Y50 F3000\n")
        with program.open("rb") as f:
            r = api.post("/jobs", files={"gcode": ("line.gcode", f)}, data={"start": "true"})
        assert r.status_code == 201, r.text
        job = r.json()["id"]
        record = wait_until("waiting for the printer",
                            lambda: (j := api.get(f"/jobs/{job}").json())["stage"] == "waiting for the printer" and j)
        assert record["state"] == "ready" and "not connected" in record["next"]["instruction"]
        printer = api.get("/printer").json()
        assert printer["state"] == "disconnected" and printer["heaters"] == {} and printer["position"] is None
        assert api.post("/printer/home").status_code == 503
        folder = daemon.state_dir / "jobs" / job
        assert (folder / "program.gcode").is_file()
        assert api.delete(f"/jobs/{job}").status_code == 204
        assert not folder.exists() and api.get(f"/jobs/{job}").status_code == 404
        assert api.get("/jobs").json() == []
    finally:
        daemon.stop()


# ---------------------------------------------------------------------------------- shared daemon


def true_mark(x: float, y: float, dx: float, dy: float, rotation_deg: float) -> tuple[float, float]:
    """Where a front-side mark (x, y) is after the flip about x = 110 and the frame put back off by
    (dx, dy), rotation_deg about the frame's centre: what the operator sees through the nozzle."""
    a = math.radians(rotation_deg)
    cx, cy = CENTER
    px, py = 2 * cx - x, y
    return (cx + math.cos(a) * (px - cx) - math.sin(a) * (py - cy) + dx,
            cy + math.sin(a) * (px - cx) + math.cos(a) * (py - cy) + dy)


def test_the_flip_and_a_jog_driven_alignment(api: httpx.Client, shared_sim: Sim, meshes: dict[str, Path]) -> None:
    """The flip told plainly (with the command to run); marks numbered from 1; for each mark the
    operator jogs the nozzle onto it and says align --here; the fit recovers the misalignment."""
    job = submit(api, meshes["two_sided"], start=True)
    flip = wait_for(api, job, "awaiting_flip", timeout=90)
    assert flip["waits_for_operator"] and flip["next"]["commands"][0] == f"ribbonctl flip-done {job}"
    assert "about its y axis" in flip["next"]["instruction"] and "x = 110" in flip["next"]["instruction"]
    assert 0 < flip["progress"] < 1 and flip["eta_s"] is None and flip["waiting_for"] == "the flip"   # issue 36
    r = api.post(f"/jobs/{job}/resume")
    assert r.status_code == 409
    assert r.json()["detail"] == "cannot resume: the job is awaiting_flip; possible now: flip-done, cancel"
    assert r.json()["allowed"] == ["flip-done", "cancel"]
    assert api.post("/printer/home").status_code == 200          # manual control while waiting

    dx, dy, rot = MISALIGNMENT
    shared_sim.flip(dx, dy, rot)
    r = api.post(f"/jobs/{job}/flip-done")
    assert r.status_code == 200 and r.json()["state"] == "aligning", r.text   # the new state
    marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
    for k, (x, y) in enumerate(marks, start=1):
        prompt = wait_for(api, job, "aligning", timeout=60, until=lambda j: j["waits_for_operator"])
        assert prompt["next"]["instruction"].startswith(f"mark {k} of {len(marks)}:"), prompt["next"]
        assert f"ribbonctl align {job} --here" in prompt["next"]["commands"]
        head = api.get("/printer").json()["head"]
        tx, ty = true_mark(x, y, dx, dy, rot)
        r = api.post("/printer/jog", json={"dx": tx - head[0], "dy": ty - head[1]})
        assert r.status_code == 200, r.text
        if k == 1:
            bad = api.post(f"/jobs/{job}/align", json={"mark": len(marks) + 1, "here": True})
            assert bad.status_code == 422 and f"marks 1 to {len(marks)}" in bad.json()["detail"]
        r = api.post(f"/jobs/{job}/align", json={"here": True})
        assert r.status_code == 200, r.text
        status = r.json()
        assert status["mark"] == k
        assert status["next_mark"] == (k + 1 if k < len(marks) else None)
    fit = status["fit"]
    assert status["accepted"]
    assert fit["rotation_deg"] == pytest.approx(rot, abs=2e-3)      # the jogs are sent to 1 µm
    assert fit["max_residual_mm"] < 5e-3
    back = wait_for(api, job, "printing_back", timeout=60)
    # (the corrected back program takes a little more or less time than the one planned)
    assert back["print_side"] == "back" and back["progress"] >= flip["progress"] - 0.01
    done = wait_for(api, job, "done", timeout=90)
    assert done["correction"]["rotation_deg"] == pytest.approx(rot, abs=2e-3)


def test_reprint_list_filter_page_and_delete(api: httpx.Client, shared_daemon: Daemon,
                                              meshes: dict[str, Path]) -> None:
    """A done job prints again (its first run kept), the list filters and pages, and delete removes
    the job and its files, refused while it prints."""
    job = submit(api, meshes["one_sided"], start=True)
    first = wait_for(api, job, "done", timeout=90)
    assert first["progress"] == 1.0 and first["eta_s"] == 0.0 and first["runs"] == []
    r = api.post(f"/jobs/{job}/start")
    assert r.status_code == 200 and r.json()["state"] == "ready" and r.json()["start_when_ready"], r.text
    printing = wait_for(api, job, "printing_front", timeout=60, poll=0.02)
    r = api.delete(f"/jobs/{job}")
    assert r.status_code == 409 and "cancel it first" in r.json()["detail"], r.text
    assert printing["ribbons"] and printing["eta_s"] is not None
    second = wait_for(api, job, "done", timeout=90)
    assert len(second["runs"]) == 1 and second["runs"][0]["state"] == "done"
    assert second["runs"][0]["lines_total"] == first["lines_total"]

    other = submit(api, meshes["one_sided"], start=False)
    wait_for(api, other, "ready", timeout=90)
    done = api.get("/jobs", params={"state": "done"})
    assert job in [j["id"] for j in done.json()] and other not in [j["id"] for j in done.json()]
    assert all(j["state"] == "done" for j in done.json())
    both = api.get("/jobs", params={"state": ["done", "ready"], "limit": 1})
    assert len(both.json()) == 1 and both.json()[0]["id"] == other       # newest first
    assert int(both.headers["x-total-count"]) >= 2
    page2 = api.get("/jobs", params={"state": ["done", "ready"], "limit": 1, "offset": 1}).json()
    assert page2[0]["id"] != other

    folder = shared_daemon.state_dir / "jobs" / job
    assert folder.is_dir()
    assert api.delete(f"/jobs/{job}").status_code == 204
    assert not folder.exists() and api.get(f"/jobs/{job}").status_code == 404
    assert api.delete(f"/jobs/{job}").status_code == 404
    assert api.delete(f"/jobs/{other}").status_code == 204


def test_plain_gcode_is_checked_line_by_line_and_printed(api: httpx.Client, shared_sim: Sim,
                                                          shared_daemon: Daemon, tmp_path: Path) -> None:
    """A G-code program the profile allows prints through the daemon, its moves deposited as
    written; one that leaves the frame or goes into the fabric is refused naming the line, nothing kept."""
    x0, y0, x1, y1 = PROFILE.frame.bounds
    good = tmp_path / "purge.gcode"
    good.write_text("; a purge line\nG28\nM104 S200\nM109 S200\nG90\nM83\nG0 Z5 F600\n"
                    f"G0 X{x0 + 10} Y{y0 + 10} F6000\nG1 Z0.2 F600\n"
                    f"G1 X{x0 + 60} Y{y0 + 10} E2.5 F900 ; the line\nG1 X{x0 + 60} Y{y0 + 12} E0.1\n"
                    "G0 Z10 F600\nM104 S0\n")
    for body, line, words in (
            (f"G28\nG90\nG0 X{x1 + 5} Y{y0 + 5} F3000\n", 3, "outside the frame"),
            (f"G28\nG90\nG0 Z5\nG0 X{x0 + 5} Y{y0 + 5} Z-0.5 F600\n", 4, "below the fabric"),
            ("G28\nM104 S400\n", 2, "nozzle_max"),
            ("G91\nG0 X5 Y5\n", 2, "relative"),
            ("G28\nG2 X30 Y30 I5 J5\n", 2, "arcs")):
        bad = tmp_path / "bad.gcode"
        bad.write_text(body)
        with bad.open("rb") as f:
            r = api.post("/jobs", files={"gcode": ("bad.gcode", f)}, data={"start": "true"})
        assert r.status_code == 422, r.text
        assert f"bad.gcode, line {line}:" in r.json()["detail"] and words in r.json()["detail"], r.json()
    uploads = shared_daemon.state_dir / "uploads"
    assert not any(uploads.iterdir())
    assert not [j for j in api.get("/jobs").json() if j["mesh_name"] == "bad.gcode"]

    first_segment = len(shared_sim.segments())
    with good.open("rb") as f:
        r = api.post("/jobs", files={"gcode": ("purge.gcode", f)}, data={"start": "true"})
    assert r.status_code == 201, r.text
    job = r.json()
    assert job["kind"] == "gcode" and job["lines_total"] == len(prepare_program(good.read_text().splitlines()))
    done = wait_for(api, job["id"], "done", timeout=60)
    states = [t["to_state"] for t in api.get(f"/jobs/{job['id']}/transitions").json()]
    assert states == ["submitted", "ready", "heating", "printing_front", "done"]
    segments = shared_sim.segments()[first_segment:]
    got = [(s["x0"], s["y0"], s["x1"], s["y1"], s["e"]) for s in segments]
    assert got == [pytest.approx((x0 + 10, y0 + 10, x0 + 60, y0 + 10, 2.5)),
                   pytest.approx((x0 + 60, y0 + 10, x0 + 60, y0 + 12, 0.1))]
    assert done["progress"] == 1.0
    assert api.get(f"/jobs/{job['id']}/files/program.gcode").text == good.read_text()
    r = api.post(f"/jobs/{job['id']}/start")                  # printed again: a new run
    assert r.status_code == 200 and r.json()["state"] == "ready"
    wait_for(api, job["id"], "done", timeout=60, until=lambda j: len(j["runs"]) == 1)


def test_a_plain_gcode_job_pauses_resumes_and_cancels_like_a_design(api: httpx.Client, shared_sim: Sim,
                                                                     tmp_path: Path) -> None:
    """The same pause (no line while paused), resume (reheat first) and cancel (heaters off, head
    lifted) as a design's program, with progress."""
    x0, y0, _, _ = PROFILE.frame.bounds
    moves = [f"G1 X{x0 + 10 + (i % 2) * 40} Y{y0 + 10 + i * 0.05:.2f} E0.2 F600" for i in range(1500)]
    program = tmp_path / "zigzag.gcode"
    program.write_text("\n".join(["G28", "M104 S210", "M109 S210", "G90", "M83", "G0 Z0.3 F600", *moves,
                                   "M104 S0"]) + "\n")
    with program.open("rb") as f:
        r = api.post("/jobs", files={"gcode": ("zigzag.gcode", f)}, data={"start": "true"})
    assert r.status_code == 201, r.text
    job = r.json()["id"]
    assert r.json()["estimate_s"]["front"] == pytest.approx(program_time(moves), rel=1e-3)
    wait_for(api, job, "printing_front", timeout=60, poll=0.02, until=lambda j: j["last_acked_line"] > 50)
    r = api.post(f"/jobs/{job}/pause")
    assert r.status_code == 200 and r.json()["state"] == "paused", r.text
    paused = r.json()
    assert 0 < paused["progress"] < 1 and paused["checkpoint"] == "front_paused"
    executed_now = len(shared_sim.program_commands())
    time.sleep(0.5)
    assert len(shared_sim.program_commands()) == executed_now, "lines went to the printer while paused"
    before = len(shared_sim.commands())
    assert api.post(f"/jobs/{job}/resume").json()["state"] == "printing_front"
    assert executed(shared_sim, before)[:2] == ["M104 S210", "M109 S210"]
    wait_for(api, job, "printing_front", timeout=30, poll=0.02,
             until=lambda j: j["last_acked_line"] > paused["checkpoint_line"] + 20)
    before = len(shared_sim.commands())
    r = api.post(f"/jobs/{job}/cancel")
    assert r.status_code == 200 and r.json()["state"] == "cancelled", r.text
    assert r.json()["last_acked_line"] < len(moves)
    after = executed(shared_sim, before)
    assert replay(after)["nozzle"] == 0.0 and f"G0 Z{PROFILE.park_lift:.3f} F{PROFILE.motion.z_speed * 60:.0f}" in after


def program_time(moves: list[str]) -> float:
    """The zigzag's time at 10 mm/s from its geometry: every move starts and ends at rest (the lift
    before is a lone Z move, and each corner is a near-reversal, where the junction speed is ~0), so
    each takes its length over the speed plus v/a (accelerating to v and back); the lift's 0.3 mm
    is too short to reach 10 mm/s: 2·sqrt(d/a)."""
    v, a = 10.0, PROFILE.motion.acceleration
    total, x, y = 2 * math.sqrt(0.3 / a), 0.0, 0.0
    for move in moves:
        words = {w[0]: float(w[1:]) for w in move.split()[1:]}
        total += math.hypot(words["X"] - x, words["Y"] - y) / v + v / a
        x, y = words["X"], words["Y"]
    return total


def test_swagger_ui_is_served_from_the_package(api: httpx.Client) -> None:
    page = api.get("/docs")
    assert page.status_code == 200
    assert "/docs-assets/swagger-ui-bundle.js" in page.text and "/docs-assets/swagger-ui.css" in page.text
    assert "cdn" not in page.text.lower() and "https://" not in page.text
    js = api.get("/docs-assets/swagger-ui-bundle.js")
    assert js.status_code == 200 and len(js.content) > 100_000
    assert api.get("/docs-assets/swagger-ui.css").status_code == 200
    assert api.get("/openapi.json").json()["paths"]["/printer/jog"]


def align_all(api: httpx.Client, job: str, marks: list[list[float]], pose: tuple[float, float, float],
              review: bool) -> dict[str, Any]:
    """Jog onto every mark of the frame put back at ``pose`` and align --here; the last status."""
    for k, (x, y) in enumerate(marks, start=1):
        wait_for(api, job, "aligning", timeout=60, until=lambda j: j["waits_for_operator"])
        head = api.get("/printer").json()["head"]
        tx, ty = true_mark(x, y, *pose)
        assert api.post("/printer/jog", json={"dx": tx - head[0], "dy": ty - head[1]}).status_code == 200
        r = api.post(f"/jobs/{job}/align", json={"here": True, "review": review})
        assert r.status_code == 200, r.text
    return r.json()


@pytest.mark.timeout(300)
def test_a_reviewed_fit_waits_then_re_seat_aligns_again_and_accept_prints(
        api: httpx.Client, shared_sim: Sim, meshes: dict[str, Path]) -> None:
    """With review, the fit waits in 'fitted' (rotation, offset, residual shown; nothing printed);
    re-seat goes back to aligning, every mark to measure again (the frame stays back side up: it is
    not turned over again); the frame seated again is aligned again, and accept prints the back
    with the second fit."""
    shared_sim.ensure_front()
    job = submit(api, meshes["two_sided"], start=True)
    wait_for(api, job, "awaiting_flip", timeout=90)
    marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
    first = (0.8, 0.4, -0.9)
    shared_sim.flip(*first)
    assert api.post(f"/jobs/{job}/flip-done").status_code == 200
    status = align_all(api, job, marks, first, review=True)
    assert status["review"] and not status.get("accepted")
    assert status["fit"]["rotation_deg"] == pytest.approx(first[2], abs=2e-3)
    fitted = wait_for(api, job, "fitted", timeout=10)
    assert fitted["waits_for_operator"] and fitted["next"]["commands"][:2] == [
        f"ribbonctl accept {job}", f"ribbonctl re-seat {job}"]
    assert f"{first[2]:.2f}°" in fitted["next"]["instruction"]
    extruded = len(shared_sim.segments())
    time.sleep(1.0)
    assert wait_for(api, job, "fitted", timeout=5)["state"] == "fitted" and len(shared_sim.segments()) == extruded
    refused = api.post(f"/jobs/{job}/align", json={"here": True})
    assert refused.status_code == 409 and "accept, re-seat, cancel" in refused.json()["detail"]

    r = api.post(f"/jobs/{job}/re-seat")
    assert r.status_code == 200 and r.json()["state"] == "aligning", r.text
    assert r.json()["error"] is None, "re-seating is a choice, not a failure"
    reseat = wait_for(api, job, "aligning", timeout=30, until=lambda j: j["waits_for_operator"])
    words = reseat["next"]["instruction"]
    assert words.startswith("Re-seat the frame, back side up (do not turn it over again); every mark is "
                            f"measured again. mark 1 of {len(marks)}:"), words
    assert "flip-done" not in words and reseat["alignment"]["kept"] == []
    second = (-0.4, 0.6, 0.5)
    shared_sim.flip()            # the frame out of its seat (the simulator turns it front up)
    shared_sim.flip(*second)     # and back in, back side up, seated a little differently
    status = align_all(api, job, marks, second, review=True)
    assert status["fit"]["rotation_deg"] == pytest.approx(second[2], abs=2e-3)
    wait_for(api, job, "fitted", timeout=10)
    r = api.post(f"/jobs/{job}/accept")
    assert r.status_code == 200 and r.json()["state"] == "printing_back", r.text
    done = wait_for(api, job, "done", timeout=120)
    assert done["correction"]["rotation_deg"] == pytest.approx(second[2], abs=2e-3)
    assert api.post(f"/jobs/{job}/accept").status_code == 409
    assert "awaiting_flip" not in [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()][6:]


@pytest.mark.timeout(300)
def test_a_refused_mark_is_measured_again_and_the_others_kept(
        api: httpx.Client, shared_sim: Sim, meshes: dict[str, Path]) -> None:
    """A mark jogged wrong (10 mm off: the marks fit no rigid motion) is refused naming it. The job
    stays aligning, back side up: the marks that fitted are kept, the head goes back above the bad
    one only, the status says so (not to turn the frame over); the refusal is cleared once the
    operator measures it again; the fit is then accepted and the back printed with it."""
    job = submit(api, meshes["two_sided"], start=True)
    wait_for(api, job, "awaiting_flip", timeout=90)
    marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
    n = len(marks)
    assert n >= 3, "one mark named as the bad one needs three or more"
    pose = (0.4, -0.3, 0.6)
    shared_sim.flip(*pose)
    assert api.post(f"/jobs/{job}/flip-done").status_code == 200
    bad = 2
    for k, (x, y) in enumerate(marks, start=1):
        wait_for(api, job, "aligning", timeout=60, until=lambda j: j["waits_for_operator"])
        head = api.get("/printer").json()["head"]
        tx, ty = true_mark(x, y, *pose)
        miss = 10.0 if k == bad else 0.0             # the nozzle put 10 mm beside the mark
        assert api.post("/printer/jog", json={"dx": tx + miss - head[0], "dy": ty - head[1]}).status_code == 200
        r = api.post(f"/jobs/{job}/align", json={"here": True})
    assert r.status_code == 409 and r.json()["refused"] == "residual", r.text
    assert f"mark {bad} is" in r.json()["detail"], r.json()["detail"]

    waiting = wait_for(api, job, "aligning", timeout=30, until=lambda j: j["waits_for_operator"])
    kept = [k for k in range(1, n + 1) if k != bad]
    assert waiting["alignment"] == {"marks": n, "kept": kept, "remeasure": [bad]}
    assert r.json()["detail"] in waiting["error"]
    words = waiting["next"]["instruction"]
    assert "The frame stays back side up (do not turn it over again)" in words, words
    assert f"measure mark {bad} again. mark {bad} of {n}:" in words, words
    assert "turn the frame over about" not in words.lower() and "flip-done" not in words, words
    # the head is above the bad mark, where it should be (the kept ones are not visited again)
    expected = (2 * CENTER[0] - marks[bad - 1][0], marks[bad - 1][1])
    assert api.get("/printer").json()["head"][:2] == pytest.approx(list(expected), abs=1e-3)
    assert [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()][-1] == "aligning"

    tx, ty = true_mark(*marks[bad - 1], *pose)
    assert api.post("/printer/jog", json={"dx": tx - expected[0], "dy": ty - expected[1]}).status_code == 200
    r = api.post(f"/jobs/{job}/align", json={"here": True})
    assert r.status_code == 200 and r.json()["accepted"], r.text
    assert r.json()["mark"] == bad and r.json()["fit"]["rotation_deg"] == pytest.approx(pose[2], abs=2e-3)
    back = wait_for(api, job, {"printing_back", "done"}, timeout=60)
    assert back["error"] is None, "the refusal is cleared once the mark is measured again"
    done = wait_for(api, job, "done", timeout=120)
    assert done["correction"]["rotation_deg"] == pytest.approx(pose[2], abs=2e-3) and done["error"] is None
