"""The job list and the New-job form (issue 36 item 11), in headless chromium against a real ribbond
and the simulator: a re-run is listed above the ended jobs while it is active, and its duration counts
from its start (read from the job's transitions), not from the job's creation; the New-job form is
one tap away on a phone; an empty file is refused before any upload (no job made); a job that failed
without a design does not say "submit the mesh again"."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.daemon.conftest import Daemon, at_gate, frame_ready, wait_for
from tests.daemon.test_frame_gate import program

from .conftest import PHONE, shot

pytestmark = pytest.mark.timeout(240)

SECOND = 1000


def duration_text(s: float) -> str:
    """A duration as the page writes it (app.js ``duration``)."""
    s = max(0, round(s))
    h, m, sec = s // 3600, (s % 3600) // 60, s % 60
    return f"{h} h {m} min" if h else f"{m} min {sec} s" if m else f"{sec} s"


def upload(api: httpx.Client, path: Path, start: bool) -> str:
    with path.open("rb") as f:
        r = api.post("/jobs", files={"gcode": (path.name, f)}, data={"start": str(start).lower()})
    assert r.status_code == 201, r.text
    return str(r.json()["id"])


def test_a_rerun_is_listed_first_and_timed_from_its_start(browser_page: Any, shared_daemon: Daemon,
                                                         api: httpx.Client, tmp_path: Path) -> None:
    rerun = upload(api, program(tmp_path, "rerun.gcode", 20), start=True)
    wait_for(api, rerun, "done", timeout=60)
    later = upload(api, program(tmp_path, "later.gcode", 5), start=False)          # newer, then ended
    assert api.post(f"/jobs/{later}/cancel").status_code == 200
    time.sleep(3.0)                                    # the re-run starts 3 s after the job's creation, at least
    assert api.post(f"/jobs/{rerun}/start").status_code == 200
    # the frame is used: the re-run waits at the gate, active
    wait_for(api, rerun, "ready", fresh_frame=False, until=at_gate)
    page = browser_page(PHONE)
    page.goto(shared_daemon.url)
    page.wait_for_selector(f"#job-list tr[data-job='{later}']", timeout=30 * SECOND)
    rows = page.locator("#job-list tr[data-job]").evaluate_all("rs => rs.map(r => r.dataset.job)")
    assert rows.index(rerun) < rows.index(later), rows                  # active first, above the cancelled one
    shot(page, "36-job-list-rerun-phone", full_page=False)
    frame_ready(api)
    done = wait_for(api, rerun, "done", timeout=60)
    restart = [t for t in api.get(f"/jobs/{rerun}/transitions").json() if (t["reason"] or "").startswith("started again")]
    assert restart, "no 'started again' transition"
    expected = duration_text(done["updated"] - restart[-1]["at"])
    since_creation = duration_text(done["updated"] - done["created"])
    assert expected != since_creation
    cell = f"#job-list tr[data-job='{rerun}'] td:nth-child(6)"
    page.wait_for_function(f"document.querySelector(\"{cell}\")?.innerText.trim() === '{expected}'",
                           timeout=20 * SECOND)
    assert not browser_page.errors, browser_page.errors


def test_the_new_job_form_is_one_tap_away_on_a_phone(browser_page: Any, shared_daemon: Daemon, api: httpx.Client,
                                                     tmp_path: Path) -> None:
    page = browser_page(PHONE)
    page.goto(shared_daemon.url)
    page.wait_for_selector("#printer")
    link = page.locator("#new-job")
    box = link.bounding_box()
    assert link.is_visible() and box["y"] + box["height"] <= PHONE["height"]
    assert page.evaluate("document.documentElement.scrollWidth") <= PHONE["width"]     # the bar still fits
    link.click()
    page.wait_for_timeout(300)
    form = page.locator("#submit-form").bounding_box()
    assert 0 <= form["y"] < PHONE["height"] / 2, form
    assert page.evaluate("document.activeElement.id") == "file"
    shot(page, "36-new-job-phone", full_page=False)
    # from a job's page too
    job = upload(api, program(tmp_path, "any.gcode", 2), start=False)
    page.goto(f"{shared_daemon.url}/#/job/{job}")
    page.wait_for_selector("#jobpage:not([hidden])")
    page.click("#new-job")
    page.wait_for_selector("#home:not([hidden])")
    page.wait_for_timeout(300)
    assert 0 <= page.locator("#submit-form").bounding_box()["y"] < PHONE["height"] / 2
    assert not browser_page.errors, browser_page.errors


def test_an_empty_file_is_refused_before_any_upload(browser_page: Any, shared_daemon: Daemon,
                                                    api: httpx.Client) -> None:
    before = {j["id"] for j in api.get("/jobs").json()}
    page = browser_page(PHONE)
    page.goto(shared_daemon.url)
    page.wait_for_selector("#submit-form")
    page.set_input_files("#file", files=[{"name": "empty.obj", "mimeType": "text/plain", "buffer": b""}])
    page.click("#submit-btn")
    page.wait_for_selector("#submit-error:not([hidden])")
    text = page.inner_text("#submit-error")
    assert "empty.obj is empty (0 bytes)" in text and "submit the mesh again" not in text
    page.wait_for_timeout(500)
    assert {j["id"] for j in api.get("/jobs").json()} == before                    # nothing made
    assert page.url.rstrip("/").endswith(shared_daemon.url.split("//")[1]) or "#/job/" not in page.url


def test_a_job_failed_without_a_design_says_what_to_do(browser_page: Any, shared_daemon: Daemon,
                                                       api: httpx.Client, tmp_path: Path) -> None:
    """A job that failed before its design existed (the daemon kept failed compiles of unreadable
    uploads): the page's advice is not to send the same file again. The job is shown as the daemon
    describes such a job (its own record, state failed, no design, only delete possible)."""
    job = upload(api, program(tmp_path, "shown.gcode", 2), start=False)
    record = api.get(f"/jobs/{job}").json()
    failed = {**record, "kind": "design", "state": "failed", "design_dir": None, "mesh_name": "empty.obj",
              "error": "empty.obj: the file is empty", "next": {"instruction": "the compile failed",
                                                                "commands": [f"ribbonctl delete {job}"]}}
    page = browser_page(PHONE)
    page.route(f"**/jobs/{job}", lambda route: route.fulfill(status=200, content_type="application/json",
                                                             body=json.dumps(failed)))
    page.route("**/jobs?limit=200", lambda route: route.fulfill(status=200, content_type="application/json",
                                                                body=json.dumps([failed])))
    page.goto(f"{shared_daemon.url}/#/job/{job}")
    page.wait_for_selector("#j-error:not([hidden])")
    words = page.inner_text("#j-next")
    assert "submit the mesh again" not in words
    assert words.startswith("Nothing to print: the file did not compile") and "New job" in words
