"""Projects (issue 26): a mesh compiled once into panels, one two-sided job per panel, queued in
order, through a real ribbond process on the simulator (real pty, real HTTP); the project's store
rows and their migration on a real SQLite file."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.daemon.jobs import JobState
from ribbond.daemon.store import SCHEMA_VERSION, JobStore, ProjectNotFound

from .conftest import PARAMETERS, ROOT, Daemon, Sim, at_gate, frame_ready, wait_for
from .test_daemon_e2e import MISALIGNMENT, flip_and_align

pytestmark = pytest.mark.timeout(240)


# ---------------------------------------------------------------------------------- the store


def test_a_project_and_its_panel_jobs_are_stored(tmp_path: Path) -> None:
    with JobStore(tmp_path / "jobs.sqlite") as store:
        p = store.create_project(project_id="prj-00000001", mesh_name="bowl.obj", mesh_path="/x/bowl.obj",
                                 parameters={"size": {"bbox_diagonal": 70}}, panels_requested="auto",
                                 seam_allowance_mm=6.0, start_when_ready=True)
        assert p.state == "submitted" and p.panel_count is None and p.folder is None
        jobs = [store.create(mesh_name="bowl.obj", mesh_path="/x/bowl.obj", parameters={}, start_when_ready=True,
                             panel=("prj-00000001", k, 3)) for k in (2, 1, 3)]
        store.create(mesh_name="other.obj", mesh_path="/x/other.obj", parameters={}, start_when_ready=False)
        assert [j.panel for j in store.project_jobs(p.id)] == [1, 2, 3]
        assert {(j.project, j.panels) for j in jobs} == {("prj-00000001", 3)}
        p = store.update_project(p.id, state="compiled", folder="/x/project", panel_count=3)
        assert (p.state, p.panel_count, p.folder) == ("compiled", 3, "/x/project")
        with pytest.raises(ValueError, match="cannot set mesh_path"):
            store.update_project(p.id, mesh_path="/y")
        with pytest.raises(ValueError, match="state"):
            store.update_project(p.id, state="printing")
        with pytest.raises(ProjectNotFound):
            store.project("prj-ffffffff")
    with JobStore(tmp_path / "jobs.sqlite") as store:        # committed: a restart finds it
        assert [q.id for q in store.projects()] == ["prj-00000001"]
        assert store.get(jobs[0].id).panel == 2


def test_a_version_5_database_gains_projects(tmp_path: Path) -> None:
    """A database of schema 5 (before projects) opens: its jobs belong to no project."""
    db = tmp_path / "jobs.sqlite"
    with JobStore(db) as store:
        job = store.create(mesh_name="m.obj", mesh_path="/m.obj", parameters={}, start_when_ready=False)
    conn = sqlite3.connect(db)                                  # back to schema 5's layout
    conn.executescript("DROP TABLE projects; DROP INDEX jobs_project; ALTER TABLE jobs DROP COLUMN project; "
                       "ALTER TABLE jobs DROP COLUMN panel; ALTER TABLE jobs DROP COLUMN panels; "
                       "PRAGMA user_version = 5;")
    conn.close()
    with JobStore(db) as store:
        old = store.get(job.id)
        assert (old.project, old.panel, old.state) == (None, None, JobState.SUBMITTED)
        assert store.projects() == [] and store.integrity() == "ok"
    assert sqlite3.connect(db).execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 6


# ---------------------------------------------------------------------------------- through the daemon


def submit_project(api: httpx.Client, mesh: Path, panels: str, *, start: bool = True) -> dict[str, Any]:
    with mesh.open("rb") as handle:
        r = api.post("/projects", files={"mesh": (mesh.name, handle)},
                     data={"parameters": json.dumps(PARAMETERS), "panels": panels, "start": str(start).lower()})
    assert r.status_code == 201, r.text
    return dict(r.json())


def wait_project(api: httpx.Client, project: str, until: Any, timeout: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while True:
        p = api.get(f"/projects/{project}").json()
        if until(p):
            return dict(p)
        assert p["state"] != "failed", p["error"]
        assert time.monotonic() < deadline, f"project {project} stuck: {p['state']} {p['next']}"
        time.sleep(0.1)


def ribbonctl(daemon: Daemon, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.client.cli", "--url", daemon.url, *args], cwd=ROOT,
                          text=True, capture_output=True, timeout=60)


def print_panel(api: httpx.Client, sim: Sim, job: str) -> dict[str, Any]:
    """One panel job as the operator prints it: a fresh fabric (front up), the front, the flip and
    the alignment, the back."""
    sim.ensure_front()
    status = wait_for(api, job, {"awaiting_flip", "done"}, timeout=90)
    if status["state"] == "awaiting_flip":
        marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
        answers = flip_and_align(api, sim, job, marks, MISALIGNMENT)
        assert all(r.status_code == 200 for r in answers), [r.text for r in answers]
        status = wait_for(api, job, "done", timeout=90)
    return status


def test_panels_are_refused_clearly(api: httpx.Client, meshes: dict[str, Path]) -> None:
    for bad in ("1", "0", "17", "many", "2.5"):
        with meshes["two_sided"].open("rb") as handle:
            r = api.post("/projects", files={"mesh": ("m.obj", handle)}, data={"panels": bad})
        assert r.status_code == 422, r.text
        assert "panels" in r.json()["detail"] and "'auto' or a whole number" in r.json()["detail"]
    assert api.get("/projects/prj-ffffffff").status_code == 404


def test_a_three_panel_project_end_to_end(api: httpx.Client, shared_sim: Sim, shared_daemon: Daemon,
                                          meshes: dict[str, Path]) -> None:
    """Compiled once, three jobs queued in order; each panel printed front, flip and alignment, back;
    between panels the project says to load a fresh stretched frame, and waits for it."""
    project = submit_project(api, meshes["two_sided"], "3")
    assert project["state"] in ("submitted", "compiling") and project["panels"] == []
    pid = project["id"]
    p = wait_project(api, pid, lambda p: p["state"] not in ("submitted", "compiling"))
    assert p["panel_count"] == 3 and [q["index"] for q in p["panels"]] == [1, 2, 3]
    assert all(len(q["outline"]) >= 3 and q["job_id"] for q in p["panels"]), p["panels"]
    jobs = [q["job_id"] for q in p["panels"]]
    for k, job in enumerate(jobs, start=1):
        record = api.get(f"/jobs/{job}").json()
        assert (record["project"], record["panel"], record["panels"]) == (pid, k, 3)
        if k > 1:              # the panel before is done: this one waits for a fresh fabric, and says so
            gate = wait_project(api, pid, lambda p: p["current_panel"] == k and p["state"] == "waiting")
            assert gate["next"]["instruction"].startswith(f"panel {k} of 3: load a fresh stretched frame")
            assert at_gate(api.get(f"/jobs/{job}").json())
            assert api.get(f"/jobs/{job}").json()["next"]["instruction"].startswith(f"panel {k} of 3")
            assert [q["state"] for q in gate["panels"]][:k - 1] == ["done"] * (k - 1)
            shown = ribbonctl(shared_daemon, "status")
            assert f"panel {k} of 3: load a fresh stretched frame" in shown.stdout, shown
            frame_ready(api)
        done = print_panel(api, shared_sim, job)
        assert done["state"] == "done"
    p = wait_project(api, pid, lambda p: p["state"] == "done")
    assert p["panels_done"] == 3 and "in this order: A (panels" in p["next"]["instruction"]
    later = [api.get(f"/jobs/{j}/transitions").json() for j in jobs]
    starts = [next(t["at"] for t in ts if t["to_state"] == "heating") for ts in later]
    assert starts == sorted(starts)                                  # printed in order
    for ts in later:                                                 # each: front, flip and alignment, back
        flow = [t["to_state"] for t in ts]
        assert flow.index("printing_front") < flow.index("awaiting_flip") < flow.index("aligning") \
            < flow.index("printing_back") < flow.index("done"), flow
    assert api.get(f"/projects/{pid}/files/project.json").json()["format"] == "ribbond-project/1"
    assert api.get(f"/projects/{pid}/files/panels.png").content[:4] == b"\x89PNG"


def test_cancelling_a_project_cancels_what_is_left(api: httpx.Client, shared_sim: Sim,
                                                   meshes: dict[str, Path]) -> None:
    project = submit_project(api, meshes["two_sided"], "2")
    pid = project["id"]
    p = wait_project(api, pid, lambda p: p["current_panel"] == 1 and p["panels"][0]["state"] == "printing_front")
    r = api.post(f"/projects/{pid}/cancel")
    assert r.status_code == 200, r.text
    p = r.json()
    assert p["state"] == "cancelled" and [q["state"] for q in p["panels"]] == ["cancelled", "cancelled"]
    assert "ribbonctl project start" in p["next"]["instruction"]
    printer = api.get("/printer", params={"refresh": "true"}).json()
    assert all((h or {}).get("target") in (0, 0.0, None) for h in (printer.get("heaters") or {}).values()), printer
    assert api.post(f"/projects/{pid}/cancel").status_code == 409              # nothing is left
