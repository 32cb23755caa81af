"""Meshes and parameters checked at upload, on every route (issue 36 items 3 and 14), against a real
daemon on the simulator.

A mesh that cannot be compiled (an empty file, a binary blob named .obj, a NaN vertex, one triangle,
a closed surface) and parameters its curvature table was not measured for are refused by ``POST
/jobs``, ``POST /projects`` and the slicer's ``POST /api/files/local`` before anything is kept: the
job and project lists, the state directory and the notification log (``GET /notifications`` and
the webhook the daemon notifies) are unchanged. Bodies with fields the document does not name are
refused with 422 on every route.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from ribbond.mesh.files import write_obj
from ribbond.design.surfaces import saddle
from ribbond.design.thickness import load_curvature_table

from .conftest import PARAMETERS, ROOT, Daemon, Sim, running
from .test_notify import Hook

pytestmark = pytest.mark.timeout(240)


def _tetrahedron(path: Path) -> None:
    """A closed surface: four faces, no boundary (Euler characteristic 2)."""
    V = np.array([[0, 0, 0], [40, 0, 0], [0, 40, 0], [0, 0, 40]], dtype=float)
    write_obj(path, V, np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]))


@pytest.fixture(scope="module")
def broken(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, list[str]]]:
    """Each broken mesh and the words its refusal must hold (the problem, and where)."""
    folder = tmp_path_factory.mktemp("broken")
    (folder / "empty.obj").write_bytes(b"")
    (folder / "blob.obj").write_bytes(np.random.default_rng(36).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    V, F = saddle(80.0, 1 / 50, 1 / 50, rings=6)
    write_obj(folder / "nan.obj", V, F)
    lines = (folder / "nan.obj").read_text(encoding="utf-8").splitlines()
    v_lines = [i for i, line in enumerate(lines) if line.startswith("v ")]
    fifth = v_lines[4]                                   # the 5th 'v' line: OBJ vertex 5
    lines[fifth] = "v 1.0 nan 2.0"
    (folder / "nan.obj").write_text("\n".join(lines) + "\n", encoding="utf-8")
    write_obj(folder / "one.obj", np.array([[0, 0, 0], [40, 0, 0], [0, 40, 0]], dtype=float), np.array([[0, 1, 2]]))
    _tetrahedron(folder / "closed.obj")
    return {"empty": (folder / "empty.obj", ["empty"]),
            "blob": (folder / "blob.obj", ["blob.obj", "binary"]),
            "nan": (folder / "nan.obj", ["NaN", f"line {fifth + 1}", "vertex 5"]),
            "one": (folder / "one.obj", ["1 face"]),
            "closed": (folder / "closed.obj", ["closed"])}


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> Path:
    V, F = saddle(80.0, 1 / 50, 1 / 50, rings=6)
    path = tmp_path_factory.mktemp("good") / "saddle.obj"
    write_obj(path, V, F)
    return path


@pytest.fixture(scope="module")
def hook() -> Iterator[Hook]:
    h = Hook()
    try:
        yield h
    finally:
        h.close()


@pytest.fixture(scope="module")
def daemon(tmp_path_factory: pytest.TempPathFactory, hook: Hook) -> Iterator[Daemon]:
    """A daemon that notifies a webhook of every event (a failed job would be told there)."""
    sim = Sim()
    try:
        with running(tmp_path_factory.mktemp("ribbond-intake"), sim.port,
                     extra=f'[notify]\nurls = ["{hook.url}"]\ntimeout_s = 5\n') as d:
            yield d
    finally:
        sim.stop()


def kept(daemon: Daemon) -> dict[str, Any]:
    """What the daemon keeps and tells: its jobs, projects, folders, uploads and notifications."""
    assert daemon.client is not None
    c = daemon.client
    folders = {sub: sorted(p.name for p in (daemon.state_dir / sub).iterdir()) if (daemon.state_dir / sub).is_dir()
               else [] for sub in ("jobs", "projects", "uploads")}
    notes = c.get("/notifications").json()
    return {"jobs": c.get("/jobs").json(), "projects": c.get("/projects").json(), "folders": folders,
            "sent": notes["sent"], "failed": notes["failed"], "deliveries": notes["deliveries"]}


def upload(c: httpx.Client, route: str, mesh: Path, parameters: dict[str, Any]) -> httpx.Response:
    """The mesh sent as each route takes it."""
    with mesh.open("rb") as handle:
        if route == "/jobs":
            return c.post("/jobs", files={"mesh": (mesh.name, handle)},
                          data={"parameters": json.dumps(parameters), "start": "true"})
        if route == "/projects":
            return c.post("/projects", files={"mesh": (mesh.name, handle)},
                          data={"parameters": json.dumps(parameters), "panels": "2", "start": "true"})
        return c.post("/api/files/local", files={"file": (mesh.name, handle)},
                      data={"print": "true", "userdata": json.dumps(parameters)})


#: Each route's refusal: ribbond's 422; the slicer's route answers OctoPrint's 400 (docs/slicers.md).
ROUTES = {"/jobs": 422, "/projects": 422, "/api/files/local": 400}


def assert_unchanged(daemon: Daemon, hook: Hook, before: dict[str, Any], heard: int) -> None:
    time.sleep(1.0)                        # a failed compile's notice would be out well within this
    assert kept(daemon) == before
    assert len(hook.got) == heard, hook.got[heard:]


@pytest.mark.parametrize("route", list(ROUTES))
@pytest.mark.timing
def test_a_broken_mesh_is_refused_at_upload_and_nothing_is_kept(daemon: Daemon, hook: Hook, route: str,
                                                                broken: dict[str, tuple[Path, list[str]]]) -> None:
    assert daemon.client is not None
    before, heard = kept(daemon), len(hook.got)
    for name, (mesh, words) in broken.items():
        t0 = time.monotonic()
        r = upload(daemon.client, route, mesh, PARAMETERS)
        took = time.monotonic() - t0
        assert r.status_code == ROUTES[route], (name, r.status_code, r.text)
        detail = r.json()["detail"]
        assert all(w in detail for w in words), (name, detail)
        assert took < 5.0, (name, took)             # read and validated, not compiled
    assert_unchanged(daemon, hook, before, heard)


@pytest.mark.parametrize("route", list(ROUTES))
def test_a_prestretch_the_table_was_not_measured_at_is_refused(daemon: Daemon, hook: Hook, route: str,
                                                               good: Path) -> None:
    """The shipped default table was measured at one pre-stretch (its file says which); 9 is refused
    naming both, where today the compile fails after a 201."""
    assert daemon.client is not None
    measured = load_curvature_table("tpu95a-lycra-default").prestretch
    assert measured != 9
    before, heard = kept(daemon), len(hook.got)
    r = upload(daemon.client, route, good, {**PARAMETERS, "prestretch": 9})
    assert r.status_code == ROUTES[route], r.text
    detail = r.json()["detail"]
    assert "prestretch = 9" in detail and f"s = {measured:g}" in detail, detail
    assert_unchanged(daemon, hook, before, heard)


def test_ribbonctl_submit_of_a_broken_mesh_leaves_no_job(daemon: Daemon, hook: Hook,
                                                         broken: dict[str, tuple[Path, list[str]]]) -> None:
    before, heard = kept(daemon), len(hook.got)
    mesh, words = broken["nan"]
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "submit", str(mesh), "--url", daemon.url],
                          cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert proc.returncode != 0
    assert all(w in proc.stderr for w in words), proc.stderr
    assert_unchanged(daemon, hook, before, heard)


def test_a_good_mesh_still_makes_a_job(daemon: Daemon, good: Path) -> None:
    """The intake refuses what is broken, not what is not: the same routes take a good mesh."""
    assert daemon.client is not None
    r = upload(daemon.client, "/jobs", good, PARAMETERS)
    assert r.status_code == 201, r.text
    job = r.json()["id"]
    assert daemon.client.post(f"/jobs/{job}/cancel").status_code == 200


# ---------------------------------------------------------------------- unknown fields (item 14)

#: A JSON body of each route with one field the document does not name.
JSON_BODIES = [("post", "/calibrations", {"junk": {"x": -1e308}}),
               ("post", "/calibrations", {"spacings": [2.0, 3.0], "spacing": [2.0]}),
               ("post", "/printer/jog", {"dx": 1.0, "dy": 1.0, "dz": 0.0, "speed": 9}),
               ("post", "/printer/goto", {"x": 100.0, "y": 100.0, "z": 5.0}),
               ("post", "/printer/heat", {"nozzle": 20, "chamber": 40}),
               ("post", "/printer/gcode", {"commands": ["M105"], "force": True}),
               ("post", "/tables", {"toml": "name = 'x'", "replace": True}),
               ("post", "/jobs/000000000000/resume", {"partial": "skip", "from_line": 3}),
               ("post", "/jobs/000000000000/frame-ok", {"keep_alignment": True, "kept": 1}),
               ("post", "/jobs/000000000000/align", {"here": True, "mark_id": 1}),
               ("post", "/jobs/000000000000/predict", {"fine": True})]


@pytest.mark.parametrize("method,path,body", JSON_BODIES, ids=[f"{p}:{sorted(b)}" for _, p, b in JSON_BODIES])
def test_an_unknown_field_is_refused_naming_it(daemon: Daemon, method: str, path: str, body: dict[str, Any]) -> None:
    assert daemon.client is not None
    before = kept(daemon)
    t0 = time.monotonic()
    r = daemon.client.request(method.upper(), path, json=body)
    assert time.monotonic() - t0 < 2.0
    assert r.status_code == 422, (path, r.status_code, r.text)
    assert "extra" in r.text.lower() or "not permitted" in r.text.lower() or "unknown" in r.text.lower(), r.text
    assert kept(daemon) == before


@pytest.mark.parametrize("route", ["/jobs", "/projects"])
@pytest.mark.parametrize("value", ["1", "yes", "on", "True", ""])
def test_a_form_boolean_takes_what_the_document_says(daemon: Daemon, good: Path, route: str, value: str) -> None:
    """``start`` is documented as a boolean; a multipart form carries it as the text true or false,
    as the document's enum says; anything else is refused, not read as one of them."""
    assert daemon.client is not None
    doc = daemon.client.get("/openapi.json").json()
    ref = doc["paths"][route]["post"]["requestBody"]["content"]["multipart/form-data"]["schema"]["$ref"]
    start = doc["components"]["schemas"][ref.rsplit("/", 1)[1]]["properties"]["start"]
    assert start.get("enum") == ["true", "false"], start
    before = kept(daemon)
    with good.open("rb") as handle:
        data = {"parameters": json.dumps(PARAMETERS), "start": value}
        r = daemon.client.post(route, files={"mesh": (good.name, handle)}, data=data)
    assert r.status_code == 422, r.text
    assert "start" in r.text
    assert kept(daemon) == before


def test_the_document_says_unknown_fields_are_refused(daemon: Daemon) -> None:
    """Every request body's schema, JSON or multipart, closes its fields (additionalProperties false)."""
    assert daemon.client is not None
    doc = daemon.client.get("/openapi.json").json()
    bodies = {}
    for path, ops in doc["paths"].items():
        for method, op in ops.items():
            for media, content in op.get("requestBody", {}).get("content", {}).items():
                ref = content["schema"].get("$ref") or next(
                    (s["$ref"] for s in content["schema"].get("anyOf", []) if "$ref" in s), None)
                if ref is not None and path != "/api/files/local":          # OctoPrint's leniency (slicers.md)
                    bodies[f"{method} {path} {media}"] = doc["components"]["schemas"][ref.rsplit("/", 1)[1]]
    assert len(bodies) >= 12, sorted(bodies)
    assert {k: s.get("additionalProperties") for k, s in bodies.items()} == {k: False for k in bodies}


@pytest.mark.parametrize("route", ["/jobs", "/projects"])
def test_an_unknown_form_field_is_refused(daemon: Daemon, good: Path, route: str) -> None:
    assert daemon.client is not None
    before = kept(daemon)
    with good.open("rb") as handle:
        r = daemon.client.post(route, files={"mesh": (good.name, handle)},
                               data={"parameters": json.dumps(PARAMETERS), "strat": "true"})
    assert r.status_code == 422, r.text
    assert "strat" in r.json()["detail"], r.text
    assert kept(daemon) == before


# ---------------------------------------------------------------------- a calibration plan (item 14)


@pytest.mark.timing
def test_a_calibration_plan_is_answered_at_once_and_made_after(daemon: Daemon) -> None:
    """``POST /calibrations`` answers within 2 s (202, ``planning``): the plan is made in the
    planner's process afterwards, and its sheets' jobs appear when it is (``ready``)."""
    assert daemon.client is not None
    c = daemon.client
    jobs_before = {j["id"] for j in c.get("/jobs").json()}
    t0 = time.monotonic()
    r = c.post("/calibrations", json={"thicknesses": [0.1, 0.3, 0.6, 0.9], "spacings": [4.0, 8.0, 14.0]})
    took = time.monotonic() - t0
    assert r.status_code == 202, r.text
    assert took < 2.0, took
    cal = r.json()
    assert cal["state"] == "planning" and cal["jobs"] == [] and cal["sheets"] is None
    deadline = time.monotonic() + 120
    while (cal := c.get(f"/calibrations/{cal['calibration']}").json())["state"] == "planning":
        assert time.monotonic() < deadline
        time.sleep(0.2)
    assert cal["state"] == "ready", cal
    assert cal["coupons"] == 4 * 3 * 2 and cal["sheets"] == len(cal["jobs"]) >= 1     # the grid × 2 sides
    assert {j["id"] for j in c.get("/jobs").json()} - jobs_before == set(cal["jobs"])
    assert all(c.get(f"/jobs/{j}").json()["state"] == "ready" for j in cal["jobs"])
    plan = c.get(f"/calibrations/{cal['calibration']}/files/plan.json").json()
    assert len(plan["sheets"]) == cal["sheets"]
    assert c.get("/calibrations/cal-00000000").status_code == 404


def test_a_coupon_larger_than_the_frame_is_refused_at_once(daemon: Daemon) -> None:
    """What the plan would refuse in the planner is checked before the answer: 422 naming it."""
    assert daemon.client is not None
    before = kept(daemon)
    r = daemon.client.post("/calibrations", json={"spacings": [4.0, 400.0]})
    assert r.status_code == 422, r.text
    assert "does not fit the frame" in r.json()["detail"]
    assert kept(daemon) == before
