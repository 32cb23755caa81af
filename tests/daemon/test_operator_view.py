"""What the operator sees (issue 22 items 4, 6, 10), end to end: real simulator processes on their
pty, real ribbond processes, ribbonctl as a subprocess.

- the design's verdict: the same lines from ``ribbonctl design``, ``ribbonctl submit``, ``ribbonctl
  status JOB`` and ``GET /jobs/{id}``; what they say follows from the surfaces' geometry (a
  hemisphere needs more area stretch at its rim than the bounds allow; a plane has κ1 = 0, below
  every curvature the table's ribbons make, so every thickness is clamped);
- the temperatures (target and actual, nozzle and bed) in ``status`` and ``watch`` while the job
  heats, and the daemon's 30 minutes of them (``GET /printer/temperatures``);
- a halted printer: the manual routes answer 409 with the state (not 503); a plain program is
  labelled as a program, not as a front; a one-sided design names only the side it prints.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from ribbond.daemon.components.temperatures import TemperatureHistory
from ribbond.mesh.files import write_obj
from ribbond.design.surfaces import plane_disk, sphere_cap
from ribbond.design.thickness import load_curvature_table
from ribbond.design.verdict import BADLY_BROKEN_PCT, verdict_lines
from ribbond.gcode.profiles import load_profile
from sim.process import SimProcess

from .conftest import BAUD, PREDICT, ROOT, Daemon, Sim, frame_ready, running, wait_for

#: The shared daemon predicts in its compiles (the harness turns that off elsewhere).
DAEMON_EXTRA = PREDICT

pytestmark = pytest.mark.timeout(240)

PROFILE = load_profile("ultimaker2-tpu")
#: A simulator slow enough that the heating lasts seconds (~12 s here; 1.6 s at the tests' usual 0.02).
HEATING_TIME_SCALE = 0.15


def ctl(daemon: Daemon, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url], cwd=ROOT,
                          text=True, capture_output=True, timeout=200)


def verdicts(text: str) -> list[str]:
    """The verdict lines of ribbonctl's output, without their label and indentation."""
    return [line.strip().removeprefix("verdict").strip() for line in text.splitlines()
            if line.strip().startswith("verdict ")]


@pytest.fixture(scope="module")
def surfaces(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("verdict-meshes")
    out = {}
    for name, (V, F) in {"hemisphere": sphere_cap(40.0, 90.0, rings=13), "plane": plane_disk(80.0, rings=6)}.items():
        out[name] = folder / f"{name}.obj"
        write_obj(out[name], V, F)
    return out


def test_the_verdict_is_the_same_everywhere(shared_daemon: Daemon, api: httpx.Client,
                                            surfaces: dict[str, Path], tmp_path: Path) -> None:
    # a plane: κ1 = 0 everywhere, below the smallest curvature of the table's ribbons
    table = load_curvature_table("tpu95a-lycra-default")
    assert min(float(table.grid("front").min()), float(table.grid("back").min())) > 0
    local = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "design", str(surfaces["plane"]), "-o",
                            str(tmp_path / "plane"), "--size", "70", "-q", "--no-optimize"], cwd=ROOT, text=True,
                           capture_output=True, timeout=200)
    assert local.returncode == 0, local.stderr
    submitted = ctl(shared_daemon, "submit", str(surfaces["plane"]), "--size", "70")
    assert submitted.returncode == 0, submitted.stderr
    job = submitted.stdout.split()[1]
    design = json.loads(api.get(f"/jobs/{job}/files/design.json").content)
    rr = design["report"]["ribbons"]
    total = rr["front"] + rr["back"]
    lines = api.get(f"/jobs/{job}").json()["verdict"]
    assert lines == verdict_lines(design)
    assert f"{total} of {total} ribbon thicknesses clamped" in lines[1], lines
    assert verdicts(local.stdout) == lines == verdicts(submitted.stdout)
    status = ctl(shared_daemon, "status", job)
    assert status.returncode == 0 and verdicts(status.stdout) == lines, status.stdout

    # a hemisphere needs more area stretch towards its rim than the bounds allow (σ1σ2 ≤ 1.3 · σ2max)
    submitted = ctl(shared_daemon, "submit", str(surfaces["hemisphere"]), "--size", "70")
    assert submitted.returncode == 0, submitted.stderr
    job = submitted.stdout.split()[1]
    record = api.get(f"/jobs/{job}").json()
    design = json.loads(api.get(f"/jobs/{job}/files/design.json").content)
    report = design["report"]
    assert max(report["sigma1_bad_pct"], report["sigma2_bad_pct"]) > BADLY_BROKEN_PCT
    assert record["verdict"] == verdict_lines(design) == verdicts(submitted.stdout)
    assert record["verdict"][0].startswith("OUTSIDE the stretch bounds")
    assert "NOT a sign of success" in record["verdict"][-1] and record["verdict"][-1].startswith("prediction")
    assert verdicts(ctl(shared_daemon, "status", job).stdout) == record["verdict"]


def test_a_one_sided_design_names_only_the_side_it_prints(shared_daemon: Daemon, api: httpx.Client,
                                                          meshes: dict[str, Path]) -> None:
    submitted = ctl(shared_daemon, "submit", str(meshes["one_sided"]), "--size", "70")
    assert submitted.returncode == 0, submitted.stderr
    job = submitted.stdout.split()[1]
    report = json.loads(api.get(f"/jobs/{job}/files/design.json").content)["report"]
    printing = {side for side in ("front", "back") if report["print"][side]["lines"]}
    assert printing == {"front"}, report["print"]         # the saddle's ribbons are all on the front
    printed = next(line for line in submitted.stdout.splitlines() if line.startswith("print "))
    words = printed.replace(",", " ").split()
    assert "front" in words and "back" not in words, printed


def test_a_plain_program_is_labelled_as_a_program(shared_daemon: Daemon, api: httpx.Client, tmp_path: Path) -> None:
    program = tmp_path / "square.gcode"
    program.write_text("G28\nG90\nM83\nG0 Z5 F600\n" + "".join(
        f"G0 X{40 + i} Y40 F6000\nG1 Z0.3 F600\nG1 X{60 + i} Y40 E1 F900\nG0 Z5 F600\n" for i in range(40)))
    printed = ctl(shared_daemon, "print", str(program))
    assert printed.returncode == 0, printed.stderr
    progress = [line for line in printed.stdout.splitlines() if line.startswith("  [")]
    assert any("%  program" in line for line in progress), printed.stdout
    assert all("front" not in line for line in progress), printed.stdout
    assert "front" not in printed.stdout.replace("front.gcode", ""), printed.stdout


class SlowSim(Sim):
    """A simulator whose heating lasts seconds (``HEATING_TIME_SCALE``)."""

    def __init__(self) -> None:  # noqa: D107 - Sim's, at another time scale
        self.process = SimProcess(["--time-scale", str(HEATING_TIME_SCALE), "--baud", str(BAUD)], cwd=ROOT).start()
        self.port = self.process.port
        self.side = "front"


@pytest.fixture(scope="module")
def slow_printer(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Sim, Daemon]]:
    sim = SlowSim()
    try:
        with running(tmp_path_factory.mktemp("ribbond-slow"), sim.port) as daemon:
            yield sim, daemon
    finally:
        sim.stop()


def test_temperatures_while_heating_in_status_watch_and_the_history(
        slow_printer: tuple[Sim, Daemon], meshes: dict[str, Path]) -> None:
    _, daemon = slow_printer
    assert daemon.client is not None
    api = daemon.client
    frame_ready(api)                    # a fresh frame loaded (this daemon's first start knows none)
    job = json.loads(ctl(daemon, "submit", str(meshes["one_sided"]), "--size", "70", "--start", "--no-wait",
                         "--json").stdout)["id"]
    watch = subprocess.Popen([sys.executable, "-m", "ribbond.client.cli", "watch", job, "--url", daemon.url], cwd=ROOT,
                             text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        wait_for(api, job, "heating", timeout=120)
        deadline = time.monotonic() + 30                  # until the printer reports the program's M109
        while (api.get("/printer").json()["heaters"].get("T") or {}).get("target") != PROFILE.temperatures.nozzle:
            assert time.monotonic() < deadline, api.get("/printer").json()
            time.sleep(0.05)
        status = ctl(daemon, "status", job)
        assert status.returncode == 0, status.stderr
        state = status.stdout.split()[1]
        temps = next(line for line in status.stdout.splitlines() if line.strip().startswith("temperatures"))
        nozzle, bed = temps.split("nozzle ")[1].split()[0], temps.split("bed ")[1].split()[0]
        # actual/target: the targets are the profile's (M109 S225; the bed stays off)
        t = PROFILE.temperatures
        assert nozzle.endswith(f"/{t.nozzle:.0f}") and bed.endswith(f"/{t.bed:.0f}"), temps
        assert state in ("heating", "printing_front"), status.stdout
        wait_for(api, job, "printing_front", timeout=120)
    finally:
        api.post(f"/jobs/{job}/cancel")
        try:
            out, err = watch.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            watch.kill()
            out, err = watch.communicate()
    heating = [line for line in out.splitlines() if line.startswith("  heating")]
    assert heating, out + err
    assert all(" °C  bed " in line and line.count("°C") == 2 for line in heating), heating
    assert any(f"/{PROFILE.temperatures.nozzle:.0f} °C" in line for line in heating), heating
    currents = [float(line.split("nozzle ")[1].split("/")[0]) for line in heating]
    assert currents == sorted(currents)                   # heating: the nozzle only warms up
    history = api.get("/printer/temperatures").json()
    samples = history["samples"]
    assert history["span_s"] == 1800 and samples
    assert samples[-1]["t"] - samples[0]["t"] <= history["span_s"]
    assert all(b["t"] - a["t"] >= history["interval_s"] for a, b in zip(samples, samples[1:]))
    assert any(s["Tt"] == PROFILE.temperatures.nozzle for s in samples)      # the heating is in it
    assert max(s["T"] for s in samples) > min(s["T"] for s in samples) + 50   # and its rise


def test_the_history_keeps_30_minutes_at_most_one_sample_a_second() -> None:
    now = [1_000_000.0]
    history = TemperatureHistory(clock=lambda: now[0])
    status = {"heaters": {"T": {"current": 20.0, "target": 225.0}, "B": {"current": 21.0, "target": 0.0}}}
    kept = 0
    for _ in range(4 * 3600 * 4):                         # four hours of polls every 0.25 s
        now[0] += 0.25
        kept += history.sample(status)
    samples = history.samples()
    assert kept == 4 * 3600                               # one a second
    assert len(samples) <= 1800 + 1
    assert now[0] - samples[0]["t"] <= 1800 and now[0] - samples[-1]["t"] < 1.0
    assert samples[-1] == {"t": samples[-1]["t"], "T": 20.0, "Tt": 225.0, "B": 21.0, "Bt": 0.0}
    assert not history.sample({"heaters": {}})            # a halted printer reports none


def test_a_halted_printer_refuses_manual_control_with_409(shared_daemon: Daemon, api: httpx.Client) -> None:
    """Last in this module: it halts the shared printer, then recovers it."""
    assert api.post("/printer/emergency-stop").status_code == 200
    try:
        for path, body in (("/printer/home", None), ("/printer/jog", {"dx": 1, "dy": 0}),
                           ("/printer/goto", {"x": 100, "y": 100}), ("/printer/gcode", {"commands": ["M105"]}),
                           ("/printer/heat", {"nozzle": 50}), ("/printer/cool", None)):
            r = api.post(path, json=body)
            assert r.status_code == 409, (path, r.status_code, r.text)
            assert r.json()["state"] == "halted" and r.json()["allowed"] == ["recover"], r.text
        home = ctl(shared_daemon, "home")
        assert home.returncode == 1 and "halted" in home.stderr and "recover" in home.stderr, home.stderr
    finally:
        assert api.post("/printer/recover", timeout=60).status_code == 200
    deadline = time.monotonic() + 30
    while api.get("/printer").json()["state"] != "ready" and time.monotonic() < deadline:
        time.sleep(0.1)


def test_a_design_is_read_once_for_its_verdict(tmp_path: Path) -> None:
    """A job list's statuses must not read every design.json (tens of MB with a fine mesh) each time:
    the verdict is kept in memory and beside the job, and read again only for another design folder."""
    from ribbond.daemon.components.verdicts import Verdicts
    from ribbond.daemon.store import JobRecord

    design_dir = tmp_path / "jobs" / "0123456789ab" / "design"
    design_dir.mkdir(parents=True)
    report = {"sigma1_bad_pct": 40.0, "sigma2_bad_pct": 0.0, "sigma1_max_dev": 0.2, "sigma2_max_dev": 0.0}
    (design_dir / "design.json").write_text(json.dumps({"report": report, "parameters": {}}))
    job = JobRecord(id="0123456789ab", state="ready", created=0, updated=0, mesh_name="m.obj", mesh_path="m.obj",
                    parameters={}, start_when_ready=False, design_dir=str(design_dir))
    expected = verdict_lines({"report": report})
    assert expected[0].startswith("OUTSIDE the stretch bounds on 40.0 % of faces")
    assert Verdicts(tmp_path / "jobs").lines(job) == expected
    (design_dir / "design.json").unlink()                      # read once: a new daemon finds it kept
    assert Verdicts(tmp_path / "jobs").lines(job) == expected
    moved = job.model_copy(update={"design_dir": str(tmp_path / "elsewhere")})
    assert Verdicts(tmp_path / "jobs").lines(moved) is None     # another folder, not written (yet)
    assert Verdicts(tmp_path / "jobs").lines(job.model_copy(update={"kind": "gcode"})) is None
