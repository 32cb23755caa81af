"""The OpenAPI document against a real daemon on the simulator (issue 16): every status a route
answers is documented with its body model, the error bodies are the documented models (one 422
model, never a string where the schema says an array), and ``schemathesis run`` with all checks,
stateful over the document's links, finds nothing (``tests/daemon/schemathesis.toml`` says where
and why a check's expected statuses are widened)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import jsonschema_rs
import pytest

from .conftest import Daemon, Sim, cancel_leftovers, running

pytestmark = pytest.mark.timeout(300)

TOKEN = "openapi-test-token"
CONFIG = Path(__file__).with_name("schemathesis.toml")
#: Examples per operation and the seed (fixed, so a failure reproduces; set them to explore more).
MAX_EXAMPLES = int(os.environ.get("RIBBOND_SCHEMATHESIS_EXAMPLES", "15"))
SEED = int(os.environ.get("RIBBOND_SCHEMATHESIS_SEED", "1"))
SAFE = {"get", "head", "options"}


@pytest.fixture(scope="module")
def fuzzed(shared_sim: Sim, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    """A daemon with a token on the simulator; small limits keep generated uploads cheap."""
    with running(tmp_path_factory.mktemp("ribbond-openapi"), shared_sim.port, api=f'token = "{TOKEN}"',
                 extra="[limits]\nmax_upload_mb = 1\nmax_faces = 2000\nmax_jobs = 20\n", token=TOKEN) as daemon:
        yield daemon


@pytest.fixture(scope="module")
def document(fuzzed: Daemon) -> dict[str, Any]:
    r = httpx.get(f"{fuzzed.url}/openapi.json")                  # open: no token needed
    assert r.status_code == 200
    return dict(r.json())


def resolve(document: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        schema = document["components"]["schemas"][schema["$ref"].rsplit("/", 1)[1]]
    return schema


def validator(document: dict[str, Any], path: str, method: str, status: int) -> Any:
    """A validator of ``status``'s JSON body as the document gives it for the operation."""
    schema = document["paths"][path][method]["responses"][str(status)]["content"]["application/json"]["schema"]
    return jsonschema_rs.validator_for({**schema, "components": document["components"]})


def test_every_status_is_documented_with_its_model(document: dict[str, Any]) -> None:
    operations = [(p, m, op) for p, ops in document["paths"].items() for m, op in ops.items()]
    assert len(operations) >= 28
    for path, method, op in operations:
        codes = set(op["responses"])
        gate = {"401", "421"} | (set() if method in SAFE else {"403"})
        assert gate <= codes, (method, path, codes)
        if "{" in path or "parameters" in op or "requestBody" in op:
            assert "422" in codes, (method, path)
        if "requestBody" in op:
            assert {"400", "413"} <= codes, (method, path)
        # the daemon has a token: a bearer token or OctoPrint's X-Api-Key header, on every operation
        assert op["security"] == [{"bearer": []}, {"apiKey": []}], (method, path)
        for code, response in op["responses"].items():
            if int(code) >= 400:
                schema = resolve(document, response["content"]["application/json"]["schema"])
                assert schema["properties"]["detail"]["type"] == "string", (method, path, code)
    for path in ("/jobs/{job_id}/start", "/printer/home", "/printer/jog", "/jobs/{job_id}/cancel"):
        assert {"409", "503"} <= set(document["paths"][path]["post"]["responses"]), path
    validation = resolve(document, document["paths"]["/jobs"]["get"]["responses"]["422"]["content"]
                         ["application/json"]["schema"])
    assert validation["properties"]["errors"]["type"] == "array"
    assert "HTTPValidationError" not in str(document["paths"])          # FastAPI's own 422 is gone
    # The lifecycle of a job is linked from its creation, of a table and a calibration too.
    links = document["paths"]["/jobs"]["post"]["responses"]["201"]["links"]
    ops = {op["operationId"] for ops in document["paths"].values() for op in ops.values()}
    assert {"job", "start", "pause", "resume", "cancel", "delete", "flip_done", "align"} <= \
        {link["operationId"] for link in links.values()}
    assert all(link["operationId"] in ops for link in links.values())
    assert all(link["parameters"] == {"job_id": "$response.body#/id"} for link in links.values())
    assert {link["operationId"] for link in
            document["paths"]["/tables"]["post"]["responses"]["201"]["links"].values()} == {"table", "remove_table"}
    assert {"GetCalibration", "GetCalibrationFile"} <= set(document["paths"]["/calibrations"]["post"]["responses"]["202"]["links"])


def test_error_bodies_are_the_documented_models(fuzzed: Daemon, document: dict[str, Any]) -> None:
    c = fuzzed.client
    assert c is not None
    cases = [
        ("/jobs", "get", c.get("/jobs", params={"limit": -1}), 422),                         # a query
        ("/printer/heat", "post", c.post("/printer/heat", json={"nozzle": 1e4}), 422),      # the service's
        ("/jobs", "post", c.post("/jobs", files={"mesh": ("m.obj", b"v 0 0 0\n")},          # a model's
                                 data={"parameters": '{"prestretch": 0.5}'}), 422),
        ("/jobs", "post", c.post("/jobs", files={"mesh": ("m.obj", b"x")}, data={"parameters": "[1"}), 422),
        ("/tables", "post", c.post("/tables", json={"toml": "= nonsense"}), 422),
        ("/tables", "post", c.post("/tables", content=b"\xff{", headers={"Content-Type": "application/json"}), 400),
        ("/jobs/{job_id}", "get", c.get("/jobs/0123456789ab"), 404),
        ("/printer/recover", "post", c.post("/printer/recover"), 409),                      # not halted
        ("/jobs", "get", httpx.get(f"{fuzzed.url}/jobs"), 401),
        ("/jobs", "get", httpx.get(f"{fuzzed.url}/jobs", headers={"Host": "evil.example"}), 421),
        ("/printer/home", "post", c.post("/printer/home", headers={"Origin": "http://evil.example"}), 403),
    ]
    for path, method, r, status in cases:
        assert r.status_code == status, (path, r.status_code, r.text)
        body = r.json()
        errors = list(validator(document, path, method, status).iter_errors(body))
        assert not errors, (path, status, body, [str(e) for e in errors])
        if status == 422:
            assert isinstance(body["detail"], str) and isinstance(body["errors"], list), body
    query = cases[0][2].json()["errors"]
    assert query[0]["loc"] == ["query", "limit"] and "input" not in query[0]
    assert [e["loc"] for e in cases[2][2].json()["errors"]] == [["prestretch"]]
    # 405 names every method of the path (GET and POST /jobs are two routes)
    r = c.put("/jobs")
    assert r.status_code == 405 and set(r.headers["allow"].split(", ")) == {"GET", "POST"}, r.headers


def test_schemathesis_finds_nothing(fuzzed: Daemon, document: dict[str, Any], tmp_path: Path) -> None:
    """All checks, coverage, fuzzing and the stateful phase over the links, a bounded number of
    examples per operation; the printer left cool afterwards."""
    cli = Path(sys.executable).with_name("schemathesis")
    command = [str(cli) if cli.exists() else "schemathesis", "--config-file", str(CONFIG), "run",
               f"{fuzzed.url}/openapi.json", "--checks", "all", "--max-examples", str(MAX_EXAMPLES),
               "--seed", str(SEED), "--workers", "1", "--request-timeout", "60", "--no-color",
               "--header", f"Authorization: Bearer {TOKEN}", "--report", "junit", "--report-dir", str(tmp_path)]
    # --workers 1: hypothesis parses lambdas with ast, which CPython 3.11 does not do safely in threads
    # cwd: schemathesis keeps a cache folder (.schemathesis) where it runs
    proc = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=280)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-12000:]
    # every operation of the document was run (the count from the document itself)
    operations = sum(1 for item in document["paths"].values() for method in item
                     if method in ("get", "put", "post", "delete", "patch", "head", "options"))
    assert "Stateful" in out and f"{operations} selected / {operations} total" in out, out[-4000:]
    assert fuzzed.proc is not None and fuzzed.proc.poll() is None, "the daemon died"
    c = fuzzed.client
    assert c is not None
    cancel_leftovers(c)                                          # a generated program may print
    if c.get("/printer").json().get("state") == "halted":       # the run sent emergency stops
        assert c.post("/printer/recover").status_code == 200
    assert c.post("/printer/cool").status_code == 200
    heaters = c.get("/printer", params={"refresh": "true"}).json()["heaters"]
    assert all(not h.get("target") for h in heaters.values()), heaters


def test_the_document_states_what_a_schema_can(fuzzed: Daemon, document: dict[str, Any]) -> None:
    """Lengths, non-empty files and allowed names are in the document, and the daemon refuses
    exactly what they exclude (so schemathesis' positive data is not refused for them)."""
    schemas = document["components"]["schemas"]
    assert schemas["Body_submit"]["properties"]["gcode"]["minLength"] == 1
    assert schemas["Body_submit"]["properties"]["mesh"]["minLength"] == 1
    assert schemas["Body_submit_project"]["properties"]["mesh"]["minLength"] == 1
    assert schemas["TableRequest"]["properties"]["toml"]["minLength"] == 1
    command = schemas["GcodeRequest"]["properties"]["commands"]["items"]
    sendable, refused_by_link = ["G28", "G1 X10 Y5 F3000 ; a move", "\tM105"], ["G1 X1*5", "; only a comment", "M117 é"]
    assert all(re.fullmatch(command["pattern"], c) for c in sendable)
    assert not any(re.fullmatch(command["pattern"], c) for c in refused_by_link)
    assert command["maxLength"] <= 95 - len("N9999999 *255")              # still sendable numbered
    profile = schemas["CalibrationRequest"]["properties"]["printer_profile"]["anyOf"][0]
    assert profile["enum"] == ["ultimaker2-tpu"]                       # the daemon's default profile
    c = fuzzed.client
    assert c is not None
    refused = [c.post("/jobs", files={"gcode": ("p.gcode", b"")}),
               c.post("/tables", json={"toml": ""}),
               c.post("/calibrations", json={"printer_profile": "prusa-mk4"}),
               c.post("/printer/gcode", json={"commands": ["G1 X1*5"]}),
               c.post("/printer/gcode", json={"commands": ["; only a comment"]}),
               c.post("/printer/gcode", json={"commands": ["M117 " + "x" * 80]})]
    for r in refused:
        assert r.status_code == 422, (r.request.url, r.text)
        assert r.json()["detail"], r.text                                # says what is wrong
