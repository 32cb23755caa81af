"""ribbonctl against a real daemon: output, --json, exit statuses, errors in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from .conftest import ROOT, Daemon, wait_for

pytestmark = pytest.mark.timeout(180)


def ctl(daemon: Daemon, *args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.cli", *args, "--url", daemon.url], cwd=ROOT,
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
    unreachable = subprocess.run([sys.executable, "-m", "ribbond.cli", "status", "--url", "http://127.0.0.1:9"],
                                 cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert unreachable.returncode == 3 and "cannot reach ribbond" in unreachable.stderr


def test_a_mesh_the_engine_refuses_fails_the_job_with_the_reason(shared_daemon: Daemon, api: httpx.Client,
                                                                 tmp_path: Path) -> None:
    closed = tmp_path / "tetra.obj"                           # a closed surface: not a disk
    closed.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    proc = ctl(shared_daemon, "submit", str(closed))
    assert proc.returncode == 1
    assert "failed" in proc.stdout and "closed" in proc.stdout
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
    wait_for(api, job, "done")
    assert api.get(f"/jobs/{job}").json()["eta_s"] is None
