"""ribbonctl against a real daemon: output, --json, exit statuses, errors in one line, the progress
bar of watch, the flip and alignment told plainly, manual control, plain G-code, a fast start."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from .conftest import ROOT, Daemon, wait_for

pytestmark = pytest.mark.timeout(180)


def ctl(daemon: Daemon, *args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url], cwd=ROOT,
                          text=True, capture_output=True, input=stdin, timeout=150)


def test_submit_waits_for_the_compile_and_prints_the_summary(shared_daemon: Daemon, api: httpx.Client,
                                                             meshes: dict[str, Path]) -> None:
    proc = ctl(shared_daemon, "submit", str(meshes["two_sided"]), "--size", "70")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("job ") and "(ready)" in lines[0]
    job = lines[0].split()[1]
    assert any(line.startswith("ribbons") and "front" in line and "back" in line for line in lines)
    preview = next(line for line in lines if line.startswith("preview"))
    assert Path(preview.split()[1]).is_file()               # the daemon's path to preview.png
    status = ctl(shared_daemon, "status", job, "--json")
    assert status.returncode == 0 and json.loads(status.stdout)["state"] == "ready"
    listing = ctl(shared_daemon, "status")
    assert job in listing.stdout and "ready" in listing.stdout
    cancel = ctl(shared_daemon, "cancel", job)
    assert cancel.returncode == 0 and "cancelled" in cancel.stdout


def test_exit_statuses_and_one_line_errors(shared_daemon: Daemon, api: httpx.Client,
                                           meshes: dict[str, Path], tmp_path: Path) -> None:
    missing = ctl(shared_daemon, "status", "0123456789ab")
    assert missing.returncode == 4 and len(missing.stderr.strip().splitlines()) == 1
    assert "no job" in missing.stderr
    submitted = ctl(shared_daemon, "submit", str(meshes["two_sided"]), "--size", "70", "--no-wait", "--json")
    job = json.loads(submitted.stdout)["id"]
    wait_for(api, job, "ready")
    refused = ctl(shared_daemon, "resume", job)             # not paused: the state does not allow it
    assert refused.returncode == 1
    assert "ready" in refused.stderr and len(refused.stderr.strip().splitlines()) == 1
    assert ctl(shared_daemon, "cancel", job).returncode == 0
    bad = tmp_path / "notes.txt"
    bad.write_text("not a mesh")
    rejected = ctl(shared_daemon, "submit", str(bad))
    assert rejected.returncode == 2 and "not a mesh file" in rejected.stderr
    unreachable = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "status", "--url", "http://127.0.0.1:9"],
                                 cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert unreachable.returncode == 3 and "cannot reach ribbond" in unreachable.stderr


def test_a_mesh_the_engine_refuses_is_refused_at_upload_with_the_reason(shared_daemon: Daemon, api: httpx.Client,
                                                                        tmp_path: Path) -> None:
    """Issue 36 item 3: refused at upload (exit status 2, the reason), no failed job left behind."""
    closed = tmp_path / "tetra.obj"                           # a closed surface: not a disk
    closed.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    before = api.get("/jobs").json()
    proc = ctl(shared_daemon, "submit", str(closed))
    assert proc.returncode == 2, proc
    assert "closed" in proc.stderr and "tetra.obj" in proc.stderr, proc.stderr
    assert api.get("/jobs").json() == before
    assert api.get("/printer").json()["state"] == "ready"     # the daemon is fine


def test_watch_follows_a_job_to_the_end_over_server_sent_events(shared_daemon: Daemon, api: httpx.Client,
                                                                meshes: dict[str, Path]) -> None:
    submitted = ctl(shared_daemon, "submit", str(meshes["one_sided"]), "--size", "70", "--start", "--no-wait",
                    "--json")
    job = json.loads(submitted.stdout)["id"]
    watched = ctl(shared_daemon, "watch", job)
    assert watched.returncode == 0, watched.stderr
    states = [line.split()[1] for line in watched.stdout.splitlines() if line.startswith(job)]
    assert states[-1] == "done"
    # the states arrive in the order of the table
    order = ["submitted", "compiling", "ready", "heating", "printing_front", "done"]
    seen = [s for s in order if s in states]
    assert seen == sorted(seen, key=order.index) and "printing_front" in seen


def test_printer_status_and_the_time_left_of_a_print(shared_daemon: Daemon, api: httpx.Client,
                                                     meshes: dict[str, Path]) -> None:
    import time

    status = api.get("/printer", params={"refresh": "true"}).json()
    assert status["state"] == "ready" and status["firmware"]
    assert "T" in status["heaters"] and status["position"] is not None and len(status["position"]) == 4
    printer = ctl(shared_daemon, "printer")
    assert printer.returncode == 0 and "ready" in printer.stdout and "°C" in printer.stdout
    job = json.loads(ctl(shared_daemon, "submit", str(meshes["one_sided"]), "--size", "70", "--start",
                         "--no-wait", "--json").stdout)["id"]
    wait_for(api, job, "printing_front")
    eta = None
    deadline = time.monotonic() + 30
    while eta is None and time.monotonic() < deadline:
        record = api.get(f"/jobs/{job}").json()
        eta = record.get("eta_s")
        if record["state"] == "done":
            break
        time.sleep(0.05)
    assert eta is not None and eta >= 0
    done = wait_for(api, job, "done")
    assert done["eta_s"] == 0.0 and done["progress"] == 1.0


def test_watch_shows_progress_and_stops_at_the_flip_with_the_command_to_run(
        shared_daemon: Daemon, api: httpx.Client, meshes: dict[str, Path]) -> None:
    """watch follows the progress events (percentages, the side, ribbon n of N) and ends when the job
    waits for the operator, printing the instruction with the exact command; status shows the
    percentage; flip-done prints the new state; global options go before the command too."""
    job = json.loads(ctl(shared_daemon, "submit", str(meshes["two_sided"]), "--size", "70", "--start",
                         "--no-wait", "--json").stdout)["id"]
    watched = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "--url", shared_daemon.url, "watch", job],
                             cwd=ROOT, text=True, capture_output=True, timeout=150)
    assert watched.returncode == 0, watched.stderr
    out = watched.stdout
    bars = [line for line in out.splitlines() if line.startswith("  [") and "%" in line]
    assert bars and any("front" in line and "ribbon " in line and "ETA" in line for line in bars), out
    percents = [float(line.split("]")[1].split("%")[0]) for line in bars]
    assert percents == sorted(percents) and 0 < percents[-1] < 100
    assert "awaiting_flip" in out.splitlines()[-3] or "awaiting_flip" in out
    assert out.rstrip().endswith(f"then run: ribbonctl flip-done {job}"), out[-400:]

    status = ctl(shared_daemon, "status", job)
    assert status.returncode == 0 and "%" in status.stdout.splitlines()[0]
    assert "next: " in status.stdout and f"ribbonctl flip-done {job}" in status.stdout
    resume = ctl(shared_daemon, "resume", job)
    assert resume.returncode == 1 and len(resume.stderr.strip().splitlines()) == 1
    assert "cannot resume: the job is awaiting_flip; possible now: flip-done, cancel" in resume.stderr
    flipped = ctl(shared_daemon, "flip-done", job)
    assert flipped.returncode == 0 and flipped.stdout.split()[1] == "aligning", flipped.stdout
    wait_for(api, job, "aligning", until=lambda j: j["waits_for_operator"])
    prompt = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "--json", "--url", shared_daemon.url, "status", job],
                            cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert json.loads(prompt.stdout)["next"]["instruction"].startswith("mark 1 of ")
    bad = ctl(shared_daemon, "align", job, "--mark", "0", "--jog", "0", "0")
    assert bad.returncode == 2 and "marks 1 to" in bad.stderr
    # interactive: a jog typed, then Enter with the nozzle on mark 1; the input ends at mark 2
    asked = ctl(shared_daemon, "align", job, stdin="0.5 -0.25\n\n")
    assert asked.returncode == 2 and "no more input" in asked.stderr, asked.stdout + asked.stderr
    assert "offset (+0.500, -0.250) mm from where it was expected" in asked.stdout, asked.stdout
    assert any(line.startswith("mark 2 of ") for line in asked.stdout.splitlines()), asked.stdout
    one = ctl(shared_daemon, "align", job, "--here")
    assert one.returncode == 0 and one.stdout.startswith("mark 2 of "), one.stdout + one.stderr
    assert ctl(shared_daemon, "cancel", job).stdout.split()[1] == "cancelled"


def test_manual_control_plain_gcode_and_delete(shared_daemon: Daemon, api: httpx.Client, tmp_path: Path) -> None:
    home = ctl(shared_daemon, "home")
    assert home.returncode == 0 and home.stdout.startswith("head at x 0.000 y 0.000 z 0.000"), home.stdout
    assert ctl(shared_daemon, "jog", "1", "1").returncode == 2            # home is outside the frame
    went = ctl(shared_daemon, "goto", "100", "100")
    assert went.returncode == 0 and "x 100.000 y 100.000" in went.stdout, went.stderr
    jogged = ctl(shared_daemon, "jog", "1.5", "-2", "0.5")
    assert jogged.returncode == 0 and "x 101.500 y 98.000 z 2.500" in jogged.stdout, jogged.stdout
    answer = ctl(shared_daemon, "gcode", "M105", "M114")
    assert answer.returncode == 0 and "> M105" in answer.stdout and "T:" in answer.stdout
    assert "X:101.50 Y:98.00 Z:2.50" in answer.stdout
    heat = ctl(shared_daemon, "heat", "--nozzle", "60")
    assert heat.returncode == 0 and "/60 °C" in heat.stdout, heat.stdout
    too_hot = ctl(shared_daemon, "heat", "--nozzle", "999")
    assert too_hot.returncode == 2 and "nozzle_max" in too_hot.stderr
    cool = ctl(shared_daemon, "cool")
    assert cool.returncode == 0 and "T " in cool.stdout and "/0 °C" in cool.stdout

    program = tmp_path / "square.gcode"
    program.write_text("G28\nG90\nM83\nG0 Z5 F600\nG0 X40 Y40 F6000\nG1 Z0.3 F600\n"
                       "G1 X60 Y40 E1 F900\nG1 X60 Y60 E1\nG0 Z10 F600\n")
    printed = ctl(shared_daemon, "print", str(program))
    assert printed.returncode == 0, printed.stderr
    job = printed.stdout.split()[0]
    assert api.get(f"/jobs/{job}").json()["state"] == "done"
    assert "done" in printed.stdout.splitlines()[-2] or "done" in printed.stdout
    bad = tmp_path / "far.gcode"
    bad.write_text("G28\nG90\nG0 X500 Y40 F6000\n")
    refused = ctl(shared_daemon, "print", str(bad))
    assert refused.returncode == 2 and "far.gcode, line 3: the move ends at x 500" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    deleted = ctl(shared_daemon, "delete", job)
    assert deleted.returncode == 0 and deleted.stdout.strip() == f"job {job} deleted"
    assert ctl(shared_daemon, "status", job).returncode == 4


def test_client_errors_version_help_and_a_fast_start(shared_daemon: Daemon, tmp_path: Path) -> None:
    run = [sys.executable, "-m", "ribbond.client.cli"]
    version = subprocess.run([*run, "--version"], cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert version.returncode == 0 and version.stdout.startswith("ribbonctl ")
    helped = subprocess.run([*run, "--help"], cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert helped.returncode == 0 and "``" not in helped.stdout and "exit status" in helped.stdout
    for command in (["submit", "missing.obj"], ["print", "missing.gcode"]):
        proc = ctl(shared_daemon, *command, "--no-wait")
        assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
        assert "No such file" in proc.stderr and "Traceback" not in proc.stderr
    bad_url = subprocess.run([*run, "status", "--url", "127.0.0.1:7125"], cwd=ROOT, text=True,
                             capture_output=True, timeout=60)
    assert bad_url.returncode == 2 and "http://HOST:PORT" in bad_url.stderr
    # the reader of the output goes away at once (ribbonctl status | head): no traceback
    proc = subprocess.Popen([*run, "status", "--url", shared_daemon.url], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    proc.stdout.close()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode in (0, 141) and "Traceback" not in err, err
    # the daemon commands load nothing of the design engine, nor a heavy HTTP library
    probe = subprocess.run([sys.executable, "-c", "import sys, ribbond.client.cli, ribbond.client.http; "
                            "print(sorted(m for m in ('numpy', 'scipy', 'matplotlib', 'httpx', 'tqdm', 'igl') "
                            "if m in sys.modules))"], cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert probe.stdout.strip() == "[]", probe.stdout + probe.stderr


def test_an_unusable_state_directory_is_a_configuration_error(tmp_path: Path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    config = tmp_path / "ribbond.toml"
    config.write_text(f'state_dir = "{blocker}/state"\n[serial]\nport = "{tmp_path}/none"\n[api]\nport = 0\n')
    proc = subprocess.run([sys.executable, "-m", "ribbond", "--config", str(config)], cwd=ROOT, text=True,
                          capture_output=True, timeout=60, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot use the state directory" in lines[0] and "Traceback" not in proc.stderr


def test_emergency_stop_shows_no_stale_temperatures_and_recover(shared_daemon: Daemon, api: httpx.Client) -> None:
    """Last in this module: it halts the shared printer, then recovers it."""
    assert "°C" in ctl(shared_daemon, "printer").stdout
    stopped = ctl(shared_daemon, "stop")
    assert stopped.returncode == 0 and "halted" in stopped.stdout
    printer = ctl(shared_daemon, "printer")
    assert printer.returncode == 0 and "halted" in printer.stdout and "°C" not in printer.stdout
    assert "ribbonctl recover" in printer.stdout
    assert ctl(shared_daemon, "home").returncode == 1                      # 409: halted
    recovered = ctl(shared_daemon, "recover")
    assert recovered.returncode == 0 and "ready" in recovered.stdout, recovered.stdout + recovered.stderr
    again = ctl(shared_daemon, "recover")
    assert again.returncode == 1 and "not halted" in again.stderr
