"""Printers that are not our simulator's stock Marlin (issue 22, items 9 and 10), end to end: a real
simulator process answering as another firmware does, or failing as a buggy one does, on its pty; a
real ribbond process; ribbonctl and HTTP.

Expectations come from the protocol and the simulator's own records (the commands it executed,
the line it swallowed), never from an earlier run.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from ribbond.printer.link import prepare_program
from sim.process import SimProcess

from .conftest import BAUD, CENTER, ROOT, TIME_SCALE, Daemon, Sim, running, submit, wait_for

pytestmark = pytest.mark.timeout(240)


class QuirkySim(Sim):
    """A simulator started with more options (another firmware's answers, an injected fault)."""

    def __init__(self, *options: str) -> None:  # noqa: D107 - Sim's attributes, other options
        self.process = SimProcess(["--time-scale", str(TIME_SCALE), "--baud", str(BAUD), *options],
                                  cwd=ROOT).start()
        self.port = self.process.port
        self.side = "front"


@contextlib.contextmanager
def quirky_printer(state_dir: Path, *options: str) -> Iterator[tuple[QuirkySim, Daemon]]:
    sim = QuirkySim(*options)
    try:
        with running(state_dir, sim.port) as daemon:
            yield sim, daemon
    finally:
        sim.stop()


def ribbonctl(daemon: Daemon, *args: str) -> dict[str, Any]:
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url, "--json"],
                          cwd=ROOT, text=True, capture_output=True, timeout=120)
    assert proc.returncode == 0, f"ribbonctl {' '.join(args)} exited {proc.returncode}: {proc.stderr}"
    return dict(json.loads(proc.stdout))


def true_mark(x: float, y: float, dx: float, dy: float, rotation_deg: float) -> tuple[float, float]:
    """A front-side mark (x, y) after the flip about x = 110, the frame put back off by (dx, dy) and
    rotation_deg about the frame's centre (sim/frame.py's model)."""
    a = math.radians(rotation_deg)
    cx, cy = CENTER
    px, py = 2 * cx - x, y
    return (cx + math.cos(a) * (px - cx) - math.sin(a) * (py - cy) + dx,
            cy + math.sin(a) * (px - cx) + math.cos(a) * (py - cy) + dy)


# ---------------------------------------------------------------------------------- item 9a


def test_a_firmware_answering_m114_on_the_ok_line_homes_jogs_and_aligns(tmp_path: Path,
                                                                      meshes: dict[str, Path]) -> None:
    """Smoothieware answers M114 with ``ok C: X:… Y:… Z:…`` and has no ADVANCED_OK: ribbonctl
    home, goto and jog work and report the printer's position, and the back side is aligned by
    jogging onto each mark and ``align --here``; the fit recovers the frame's misalignment."""
    with quirky_printer(tmp_path / "state", "--m114-on-ok", "--no-advanced-ok") as (sim, daemon):
        homed = ribbonctl(daemon, "home")
        assert homed["position"][:3] == [0.0, 0.0, 0.0], homed
        went = ribbonctl(daemon, "goto", "60", "70")
        assert went["position"][:2] == [60.0, 70.0], went
        jogged = ribbonctl(daemon, "jog", "1.5", "-2")
        assert jogged["position"][:2] == [61.5, 68.0], jogged
        assert daemon.client is not None
        # the printer's own report (asked again: M114, answered on the ok line) agrees
        status = daemon.client.get("/printer", params={"refresh": "true"}).json()
        assert status["position"][:2] == [61.5, 68.0], status
        answers = [c for c in sim.commands() if c["command"] == "M114"]
        assert answers, "the positions came from M114"

        api = daemon.client
        job = submit(api, meshes["two_sided"], start=True)
        wait_for(api, job, "awaiting_flip", timeout=90)
        dx, dy, rot = (0.5, -0.3, 0.7)
        sim.flip(dx, dy, rot)
        assert api.post(f"/jobs/{job}/flip-done").status_code == 200
        marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
        for k, (x, y) in enumerate(marks, start=1):
            wait_for(api, job, "aligning", timeout=60, until=lambda j: j["waits_for_operator"])
            head = api.get("/printer").json()["head"]
            tx, ty = true_mark(x, y, dx, dy, rot)
            ribbonctl(daemon, "jog", f"{tx - head[0]:.4f}", f"{ty - head[1]:.4f}")
            status = ribbonctl(daemon, "align", job, "--here")
            assert status["mark"] == k
        assert status["accepted"], status
        assert status["fit"]["rotation_deg"] == pytest.approx(rot, abs=2e-3)
        done = wait_for(api, job, "done", timeout=120)
        assert done["correction"]["rotation_deg"] == pytest.approx(rot, abs=2e-3)


# ---------------------------------------------------------------------------------- item 9b


def test_a_swallowed_resent_line_interrupts_the_job_naming_it_and_resume_prints_it(
        tmp_path: Path, meshes: dict[str, Path]) -> None:
    """The printer asks for line N again, takes the re-sent N without running or answering it and
    later asks for N + 1: the job does not end done; it is interrupted with the line named, N never
    ran (the simulator's record), and a resume prints from before it, so N runs."""
    with quirky_printer(tmp_path / "state", "--swallow-resent-after-lines", "600") as (sim, daemon):
        api = daemon.client
        assert api is not None
        job = submit(api, meshes["one_sided"], start=True)
        stopped = wait_for(api, job, "interrupted", timeout=120)
        swallowed = sim.request({"cmd": "stats"})["stats"]["swallowed_line"]
        assert swallowed > 0, "the fault must have fired"
        match = re.search(r"never line (\d+) \(program line (\d+): ([^)]*)\)", stopped["error"] or "")
        assert match, stopped["error"]
        assert int(match.group(1)) == swallowed
        index = int(match.group(2)) - 1
        front = prepare_program(Path(stopped["design_dir"], "front.gcode").read_text(encoding="utf-8").splitlines())
        assert front[index] == match.group(3)
        assert swallowed not in [c["line"] for c in sim.commands()], "line N never ran"
        before = len(sim.commands())
        assert stopped["last_acked_line"] < index + 1, "nothing from the line named on counts as done"

        r = api.post(f"/jobs/{job}/resume", json={"partial": "reprint"})
        assert r.status_code == 200, r.text
        wait_for(api, job, "awaiting_check", timeout=60, until=lambda j: j["waits_for_operator"])
        assert api.post(f"/jobs/{job}/frame-ok", json={"keep_alignment": False}).status_code == 200
        wait_for(api, job, "done", timeout=120)
        rerun = [c["command"] for c in sim.commands()[before:]]
        assert front[index] in rerun, "the resumed run printed the line that never ran"


# ---------------------------------------------------------------------------------- issue 36


def test_a_marlin_named_firmware_printing_the_position_after_its_ok_homes_and_jogs(tmp_path: Path) -> None:
    """A build that names itself Marlin 2 but prints M114's report after its ok (OctoPrint's virtual
    printer: okBeforeCommandOutput): ribbonctl home, goto and jog report the printer's position, and
    the printer's own report, asked again, agrees."""
    with quirky_printer(tmp_path / "state", "--dialect", "marlin2", "--ok-before-output") as (sim, daemon):
        assert daemon.client is not None
        assert daemon.client.get("/printer").json()["firmware"].startswith("Marlin 2.")
        homed = ribbonctl(daemon, "home")
        assert homed["position"][:3] == [0.0, 0.0, 0.0], homed
        went = ribbonctl(daemon, "goto", "60", "70")
        assert went["position"][:2] == [60.0, 70.0], went
        jogged = ribbonctl(daemon, "jog", "1.5", "-2")
        assert jogged["position"][:2] == [61.5, 68.0], jogged
        status = daemon.client.get("/printer", params={"refresh": "true"}).json()
        assert status["position"][:2] == [61.5, 68.0], status
        assert [c for c in sim.commands() if c["command"] == "M114"], "the positions came from M114"


def test_a_resent_line_never_run_on_plain_ok_firmware_interrupts_a_two_sided_job_and_resume_ends_it_done(
        tmp_path: Path, meshes: dict[str, Path]) -> None:
    """Plain-ok Marlin that times out after a resend request: it refuses line N, asks for it,
    marks the re-sent N received without running or answering it, and takes N + 1 next. The job
    is interrupted naming N and its program line (N never ran, nothing after it ran either); a
    resume reprinting the part prints N, the job goes on through the flip to ``done``, and every
    extruding move of both sides was laid down once, except the reprinted part's (then again)."""
    from .deposits import executed, outcome, program_parts
    from .test_daemon_e2e import flip_and_align

    with quirky_printer(tmp_path / "state", "--no-advanced-ok", "--ignore-resent-after-lines", "500") as (sim, daemon):
        api = daemon.client
        assert api is not None
        job = submit(api, meshes["two_sided"], start=True)
        stopped = wait_for(api, job, "interrupted", timeout=120)
        ignored = sim.request({"cmd": "stats"})["stats"]["ignored_resent_line"]
        assert ignored > 0, "the fault must have fired"
        match = re.search(r"line (\d+) \(program line (\d+): ([^)]*)\)", stopped["error"] or "")
        assert match, stopped["error"]
        assert int(match.group(1)) == ignored
        front_text = Path(stopped["design_dir"], "front.gcode").read_text(encoding="utf-8")
        front = prepare_program(front_text.splitlines())
        index = int(match.group(2)) - 1
        assert front[index] == match.group(3)
        assert ignored not in [c["line"] for c in sim.commands()], "line N never ran"
        assert front[index + 1] not in [c["command"] for c in sim.commands()], "nor anything after it"
        assert stopped["last_acked_line"] < index + 1, "nothing from the line named on counts as done"
        before = len(sim.commands())

        r = api.post(f"/jobs/{job}/resume", json={"partial": "reprint"})
        assert r.status_code == 200, r.text
        wait_for(api, job, "awaiting_check", timeout=60, until=lambda j: j["waits_for_operator"])
        assert api.post(f"/jobs/{job}/frame-ok", json={"keep_alignment": False}).status_code == 200
        wait_for(api, job, "awaiting_flip", timeout=120)
        assert front[index] in [c["command"] for c in sim.commands()[before:]], "the resume printed line N"
        marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
        answers = flip_and_align(api, sim, job, marks, (0.4, -0.3, 0.6))
        assert all(a.status_code == 200 for a in answers), [a.text for a in answers]
        wait_for(api, job, "done", timeout=150)
        back_text = (daemon.state_dir / "jobs" / job / "back-corrected.gcode").read_text(encoding="utf-8")
        segments = sim.segments()
        front_parts, back_parts = program_parts(front_text), program_parts(back_text)
        front_result = [outcome(p, executed(segments, "front")) for p in front_parts]
        back_result = [outcome(p, executed(segments, "back")) for p in back_parts]
        assert all(o == "full" for o in back_result), back_result
        assert front_result.count("over") <= 1 and set(front_result) <= {"full", "over"}, front_result


# ---------------------------------------------------------------------------------- item 10


def test_an_unplugged_printer_is_one_error_line_and_the_job_interrupted(tmp_path: Path,
                                                                       meshes: dict[str, Path]) -> None:
    """The pty closed mid-stream (a USB cable pulled): the log says so in one ERROR line naming the
    port, with no traceback; the job is interrupted as before."""
    with quirky_printer(tmp_path / "state") as (sim, daemon):
        api = daemon.client
        assert api is not None
        job = submit(api, meshes["one_sided"], start=True)
        wait_for(api, job, "printing_front", timeout=90, until=lambda j: j["last_acked_line"] > 50)
        port = sim.port
        sim.request({"cmd": "disconnect"})
        stopped = wait_for(api, job, "interrupted", timeout=60)
        assert "disconnected" in (stopped["error"] or ""), stopped["error"]
        time.sleep(0.5)                               # the print task's own lines after the stop
        log = daemon.log_path.read_text(encoding="utf-8", errors="replace")
        errors = [line for line in log.splitlines() if " ERROR " in line]
        unplugged = [line for line in errors if "printer disconnected:" in line]
        assert len(unplugged) == 1, errors
        assert f"printer disconnected: {port}:" in unplugged[0] and "reconnect" in unplugged[0], unplugged
        assert "Traceback" not in log, log[-3000:]
