"""``POST /jobs/{id}/predict`` on a real daemon (issue 23 item 4): the job's design predicted again in
a worker process, its progress and result in the job's status, its design folder's prediction
replaced, and the refusals (404 unknown job, 422 unknown table, 409 while compiling, while a
prediction runs, for a job without a design folder)."""

from __future__ import annotations

import time
import tomllib
from pathlib import Path
from typing import Any

import httpx

from ribbond.design.format import DeployedReport
from ribbond.design.thickness import TABLE_DIR
from ribbond.design.verdict import verdict_lines

from .conftest import PREDICT, Daemon, fresh_copy, submit, wait_for

#: The shared daemon predicts in its compiles (the harness turns that off elsewhere).
DAEMON_EXTRA = PREDICT

SHIPPED = "tpu95a-lycra-default"


def wait_prediction(api: httpx.Client, job: str, timeout: float = 120.0) -> tuple[dict[str, Any], list[str]]:
    """Poll the job until its prediction is no longer running: the job and the prediction states seen."""
    seen: list[str] = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        j = api.get(f"/jobs/{job}").json()
        state = (j.get("prediction") or {}).get("state")
        if not seen or seen[-1] != state:
            seen.append(state)
        if state in ("done", "failed"):
            return j, seen
        time.sleep(0.05)
    raise AssertionError(f"the prediction of job {job} did not end in {timeout:.0f} s; seen {seen}")


def half_table_toml() -> str:
    """The shipped table with every κ halved, named ``half-kappa`` (same pre-stretch)."""
    t = tomllib.loads((TABLE_DIR / f"{SHIPPED}.toml").read_text(encoding="utf-8"))
    rows = lambda side: "[" + ", ".join(str([k / 2 for k in row]) for row in t[side]) + "]"  # noqa: E731
    return (f'name = "half-kappa"\nprestretch = {t["prestretch"]!r}\nthickness = {t["thickness"]}\n'
            f'spacing = {t["spacing"]}\nfront = {rows("front")}\nback = {rows("back")}\n')


def test_predict_a_ready_job_again(shared_daemon: Daemon, api: httpx.Client, meshes: dict[str, Path],
                                   tmp_path: Path) -> None:
    # bytes no compile cache holds: the compile runs while the first prediction is asked for
    job = submit(api, fresh_copy(meshes["two_sided"], tmp_path), start=False)
    assert api.post(f"/jobs/{job}/predict").status_code == 409          # still compiling: the compile predicts
    before = wait_for(api, job, "ready", timeout=120)
    assert before["prediction"] is None
    old_obj = api.get(f"/jobs/{job}/files/deployed.obj").content     # [design] predict = true: the compile's
    assert old_obj
    design_dir = Path(before["design_dir"])
    kept = {n: (design_dir / n).stat().st_ino for n in ("front.gcode", "back.gcode", "target.obj", "flat.obj")}

    r = api.post(f"/jobs/{job}/predict", json={})
    assert r.status_code == 202, r.text
    assert r.json()["prediction"]["state"] == "running" and r.json()["state"] == "ready"
    again = api.post(f"/jobs/{job}/predict")
    assert again.status_code == 409 and "already running" in again.json()["detail"]
    assert api.delete(f"/jobs/{job}").status_code == 409

    after, seen = wait_prediction(api, job)
    assert seen[0] == "running" and seen[-1] == "done", seen
    p = after["prediction"]
    assert after["state"] == "ready" and p["fraction"] == 1.0
    design = api.get(f"/jobs/{job}/files/design.json").json()
    assert p["deployed"] == design["report"]["deployed"]
    assert after["verdict"] == verdict_lines(design) == p["verdict"]
    assert api.get(f"/jobs/{job}/files/deployed.obj").content.count(b"\nv ") > 0
    assert old_obj.count(b"\nf ") == api.get(f"/jobs/{job}/files/deployed.obj").content.count(b"\nf ")
    assert {n: (design_dir / n).stat().st_ino for n in kept} == kept   # the programs untouched
    assert (Path(shared_daemon.state_dir) / "jobs" / job / "predict.log").is_file()


def test_predict_with_another_daemon_table(shared_daemon: Daemon, api: httpx.Client,
                                           meshes: dict[str, Path]) -> None:
    job = submit(api, meshes["one_sided"], start=False)
    wait_for(api, job, "ready", timeout=120)
    own = api.get(f"/jobs/{job}/files/design.json").json()["report"]["deployed"]["deviation_pct"]["mean"]
    bad = api.post(f"/jobs/{job}/predict", json={"table": "no-such-table"})
    assert bad.status_code == 422 and "no-such-table" in bad.text
    assert api.get(f"/jobs/{job}").json()["prediction"] is None          # nothing started
    assert api.post("/tables", json={"toml": half_table_toml()}).status_code == 201
    try:
        assert api.post(f"/jobs/{job}/predict", json={"table": "half-kappa"}).status_code == 202
        after, _ = wait_prediction(api, job)
    finally:
        api.delete("/tables/half-kappa")
    p = after["prediction"]
    design = api.get(f"/jobs/{job}/files/design.json").json()
    if "table" not in DeployedReport.model_fields:                      # the format cannot record it
        assert p["state"] == "failed" and "report.deployed.table" in p["error"]
        assert design["report"]["deployed"]["deviation_pct"]["mean"] == own
        return
    assert p["state"] == "done" and p["table"] == "half-kappa"
    assert design["report"]["deployed"]["table"] == "half-kappa"
    assert design["parameters"]["curvature_table"] == SHIPPED
    # half the curvature bends the sheet less: the target is missed by more
    assert design["report"]["deployed"]["deviation_pct"]["mean"] > own


def test_unknown_job_and_a_plain_program(api: httpx.Client, tmp_path: Path) -> None:
    assert api.post("/jobs/0123456789ab/predict").status_code == 404
    program = tmp_path / "p.gcode"
    program.write_text("G28\nG1 X50 Y50 F3000\n")
    with program.open("rb") as handle:
        r = api.post("/jobs", files={"gcode": ("p.gcode", handle)}, data={"start": "false"})
    assert r.status_code == 201, r.text
    refused = api.post(f"/jobs/{r.json()['id']}/predict")
    assert refused.status_code == 409 and "no design folder" in refused.json()["detail"]
    api.delete(f"/jobs/{r.json()['id']}")


def test_ribbonctl_predict_job(shared_daemon: Daemon, api: httpx.Client, meshes: dict[str, Path]) -> None:
    """``ribbonctl predict --job ID`` asks the daemon and prints what the job's prediction says."""
    from .test_operator_view import ctl, verdicts

    job = submit(api, meshes["two_sided"], start=False)
    wait_for(api, job, "ready", timeout=120)
    r = ctl(shared_daemon, "predict", "--job", job)
    assert r.returncode == 0, (r.stdout, r.stderr)
    record = api.get(f"/jobs/{job}").json()
    deployed = api.get(f"/jobs/{job}/files/design.json").json()["report"]["deployed"]
    assert verdicts(r.stdout) == record["verdict"]
    assert f"mean {deployed['deviation_pct']['mean']:.2f} %" in r.stdout
    assert ctl(shared_daemon, "predict", "--job", "0123456789ab").returncode == 4
    both = ctl(shared_daemon, "predict", "/tmp", "--job", job)
    assert both.returncode == 2 and "either a design folder or --job" in both.stderr
