"""Submits that used to lose or hide things (issue 16), against a real daemon on the simulator.

A 300-byte file name, the daemon's ``[limits] max_faces``, a ``[solver]`` table in ``--params``,
parameters the engine cannot use (refused at submit naming the field sent), and designs that would
print nothing. Every failure path leaves the job count, the queue and the state directory as
they were, also across a restart.
"""

from __future__ import annotations

import asyncio
import json
import sqlite3
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.daemon.config import DaemonConfig
from ribbond.daemon.service import MAX_NAME_BYTES, RibbonService, mesh_file_name
from ribbond.daemon.store import JobStore
from ribbond.mesh.files import write_obj
from ribbond.design.surfaces import saddle
from ribbond.gcode.profiles import load_profile

from .conftest import ROOT, Daemon, Sim, cancel_leftovers, wait_for

pytestmark = pytest.mark.timeout(240)

#: The daemon's limits in these tests (written to its configuration below).
MAX_FACES = 500
MAX_JOBS = 3
SIZE = {"size": {"bbox_diagonal": 70}}


@pytest.fixture(scope="module")
def meshes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, int]]:
    """``small``: a saddle under MAX_FACES; ``large``: the same saddle over it (path, faces)."""
    folder = tmp_path_factory.mktemp("submit-meshes")
    out = {}
    for name, rings in {"small": 8, "large": 12}.items():
        V, F = saddle(80.0, 1 / 50, 1 / 50, rings=rings)
        write_obj(folder / f"{name}.obj", V, F)
        out[name] = (folder / f"{name}.obj", len(F))
    assert out["small"][1] <= MAX_FACES < out["large"][1]
    return out


@pytest.fixture(scope="module")
def small(meshes: dict[str, tuple[Path, int]]) -> Path:
    return meshes["small"][0]


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    sim = Sim()
    d = Daemon(tmp_path_factory.mktemp("ribbond-submit"), sim.port,
               extra=f"[limits]\nmax_faces = {MAX_FACES}\nmax_jobs = {MAX_JOBS}\n")
    try:
        d.start()
        yield d
    finally:
        d.stop()
        sim.stop()


@pytest.fixture
def client(daemon: Daemon) -> Iterator[httpx.Client]:
    assert daemon.client is not None
    try:
        yield daemon.client
    finally:
        if daemon.client is not None:
            cancel_leftovers(daemon.client)


def post(client: httpx.Client, mesh: Path, parameters: dict[str, Any], name: str | None = None,
         start: bool = False) -> httpx.Response:
    with mesh.open("rb") as handle:
        return client.post("/jobs", files={"mesh": (name or mesh.name, handle)},
                           data={"parameters": json.dumps(parameters), "start": str(start).lower()})


def state_files(daemon: Daemon) -> set[str]:
    """Every job folder and upload the daemon keeps."""
    folders = {p.name for p in (daemon.state_dir / "jobs").iterdir()}
    uploads = {p.name for p in (daemon.state_dir / "uploads").iterdir()} if (daemon.state_dir / "uploads").exists() \
        else set()
    return folders | {f"uploads/{u}" for u in uploads}


def design_report(job: dict[str, Any]) -> dict[str, Any]:
    design = json.loads((Path(job["design_dir"]) / "design.json").read_text(encoding="utf-8"))
    return dict(design["report"])


def test_a_300_byte_name_is_shortened_and_compiles(client: httpx.Client, small: Path) -> None:
    long_name = "a" * 150 + "b" * 146 + ".obj"
    assert len(long_name.encode()) == 300
    r = post(client, small, SIZE, name=long_name)
    assert r.status_code == 201, r.text
    job = r.json()
    stored = job["mesh_name"]
    assert len(stored.encode()) <= 120 and stored.startswith("a" * 100) and stored.endswith(".obj")
    assert Path(job["mesh_path"]).name == stored and Path(job["mesh_path"]).is_file()
    wait_for(client, job["id"], "ready", timeout=120)


def test_long_names_stay_readable_and_apart() -> None:
    first, second = "p" * 200 + "q" * 96 + ".obj", "p" * 200 + "r" * 96 + ".obj"
    a, b = mesh_file_name(first), mesh_file_name(second)
    assert a != b and a.startswith("p" * 100) and a.endswith(".obj") and len(a.encode()) <= MAX_NAME_BYTES
    accented = mesh_file_name("é" * 150 + ".stl")            # 304 bytes of UTF-8
    assert accented.endswith(".stl") and len(accented.encode()) <= MAX_NAME_BYTES
    assert mesh_file_name("saddle.obj") == "saddle.obj"       # short names unchanged


def test_refused_submits_leave_no_job_and_no_file(daemon: Daemon, client: httpx.Client,
                                                  small: Path) -> None:
    before_jobs = client.get("/jobs").json()
    before_files = state_files(daemon)
    refusals = {
        "ribbon_length = inf": {"ribbon_length": float("inf")},
        "size.bbox_diagonal = 1e-09": {"size": {"bbox_diagonal": 1e-9}},
        "min_ribbon_length = 1e+09": {"min_ribbon_length": 1e9},
        "solver.max_iteration": {"solver": {"max_iteration": 1}},            # a misspelt key
        "colour": {"colour": "red"},
        "solver.max_faces = 100000": {"solver": {"max_faces": 100_000}},     # above [limits] max_faces
        "solver.refine_method = 'cubic'": {"solver": {"refine_method": "cubic"}},   # not a refinement scheme
    }
    for field, parameters in refusals.items():
        r = post(client, small, parameters, name="x" * 300 + ".obj")
        assert r.status_code == 422, (parameters, r.text)
        assert field in r.text, (field, r.text)
        assert "sigma2_bounds = [" not in r.text and "F must have" not in r.text   # derived, not sent
    assert client.get("/jobs").json() == before_jobs
    assert state_files(daemon) == before_files


def test_the_queue_limit_is_not_used_up_by_refused_submits(client: httpx.Client, small: Path) -> None:
    for _ in range(MAX_JOBS + 2):
        assert post(client, small, {"ribbon_length": float("nan")}, start=True).status_code == 422
    # jobs to print as soon as compiled count against max_jobs until they end (cancelled after the test);
    # long names, which once failed after their row was written
    queued = [post(client, small, SIZE, start=True, name=f"{k}" * 300 + ".obj") for k in range(MAX_JOBS)]
    assert [r.status_code for r in queued] == [201] * MAX_JOBS, [r.text for r in queued]
    full = post(client, small, SIZE, start=True)
    assert full.status_code == 409 and "max_jobs" in full.text


def test_a_failure_after_the_upload_is_stored_leaves_nothing(tmp_path: Path, small: Path) -> None:
    """In process, with the real store: its write fails after the mesh was moved into place."""
    config = DaemonConfig(state_dir=tmp_path / "state")
    store = JobStore(tmp_path / "jobs.sqlite")
    service = RibbonService(config, load_profile(config.printer_profile), store, None)
    upload = tmp_path / "upload-1"
    upload.write_bytes(small.read_bytes())
    store.close()                                             # every write now raises
    with pytest.raises(sqlite3.Error):
        asyncio.run(service.submit(upload, "w" * 300 + ".obj", dict(SIZE), start=False))
    assert list(service.jobs_dir.iterdir()) == []
    with JobStore(tmp_path / "jobs.sqlite") as reopened:
        assert reopened.count() == 0


def test_the_daemons_max_faces_is_checked_at_upload(client: httpx.Client,
                                                    meshes: dict[str, tuple[Path, int]]) -> None:
    """The mesh is read at upload as the compile's intake reads it (issue 36 item 3): a mesh over the
    daemon's ``[limits] max_faces`` is refused there, naming both counts and the limit, no job made."""
    large, faces = meshes["large"]
    before = client.get("/jobs").json()
    r = post(client, large, SIZE)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert "[limits] max_faces" in detail and str(faces) in detail and str(MAX_FACES) in detail, detail
    assert client.get("/jobs").json() == before


def test_solver_settings_take_effect(client: httpx.Client, small: Path) -> None:
    plain = post(client, small, SIZE).json()
    capped = post(client, small, {**SIZE, "solver": {"max_iterations": 1}}).json()
    plain_report = design_report(wait_for(client, plain["id"], "ready", timeout=120))
    capped_report = design_report(wait_for(client, capped["id"], "ready", timeout=120))
    assert plain_report["iterations"] > 1                     # the cap below is what changes it
    assert capped_report["iterations"] == 1
    assert capped["parameters"]["solver"] == {"max_iterations": 1}


def test_ribbonctl_forwards_the_solver_table(daemon: Daemon, client: httpx.Client,
                                             small: Path, tmp_path: Path) -> None:
    params = tmp_path / "params.toml"
    params.write_text("ribbon_length = 15.0\n[size]\nbbox_diagonal = 70\n[solver]\nmax_iterations = 1\n",
                      encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "submit", str(small),
                           "--params", str(params), "--no-wait", "--json", "--url", daemon.url],
                          cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    job = json.loads(proc.stdout)
    assert job["parameters"]["solver"] == {"max_iterations": 1}
    assert design_report(wait_for(client, job["id"], "ready", timeout=120))["iterations"] == 1
    params.write_text("[solver]\nmax_iterations = 1\nmax_iteration = 2\n", encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "submit", str(small),
                           "--params", str(params), "--no-wait", "--url", daemon.url],
                          cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert proc.returncode != 0 and "solver.max_iteration" in proc.stderr


def test_a_design_without_ribbons_fails_naming_the_cause(client: httpx.Client, small: Path) -> None:
    # 2 mm across: larger than a ribbon's width (accepted at submit), too small for any ribbon
    job = post(client, small, {"size": {"bbox_diagonal": 2.0}}).json()
    failed = wait_for(client, job["id"], "failed", timeout=120)
    assert "no ribbons" in failed["error"] and "size" in failed["error"]


def test_a_restart_finds_no_orphan(daemon: Daemon, small: Path) -> None:
    assert daemon.client is not None
    r = post(daemon.client, small, {"ribbon_length": float("inf")}, name="y" * 300 + ".obj")
    assert r.status_code == 422
    cancel_leftovers(daemon.client)
    jobs = {j["id"]: j["state"] for j in daemon.client.get("/jobs").json()}
    stray = daemon.state_dir / "jobs" / "0123456789ab"       # as if stopped between the upload and its row
    stray.mkdir()
    (stray / "mesh.obj").write_bytes(small.read_bytes())
    daemon.stop()
    daemon.start()
    assert daemon.client is not None
    after = {j["id"]: j["state"] for j in daemon.client.get("/jobs").json()}
    assert after == jobs                                      # nothing new, nothing resurrected
    assert not stray.exists()
    assert {p.name for p in (daemon.state_dir / "jobs").iterdir()} <= set(after)


def test_an_orphan_an_older_daemon_left_fails_clearly(tmp_path: Path) -> None:
    """A row in ``submitted`` whose upload never reached its folder (the old order: row first)."""
    sim = Sim()
    d = Daemon(tmp_path / "state", sim.port)
    try:
        with JobStore(d.state_dir / "jobs.sqlite3") as store:
            orphan = store.create(mesh_name="a" * 250 + ".obj", mesh_path=str(d.state_dir / "uploads" / "upload-gone"),
                                  parameters=dict(SIZE), start_when_ready=False)
        d.start()
        assert d.client is not None
        failed = wait_for(d.client, orphan.id, "failed", timeout=60)
        assert "never stored" in failed["error"] and "submit it again" in failed["error"]
    finally:
        d.stop()
        sim.stop()
