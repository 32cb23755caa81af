"""A project's end and its verdict (issue 36 item 7), end to end: a real simulator on its pty, a real
ribbond process with notifications to a loopback webhook, ribbonctl as a subprocess.

The last panel printed is not an ordinary "Done … print it again": the job, the project and the
notification say that all N panels are printed and which seams to sew, in their order (project.json's
seams); a panel before it keeps the ordinary notice. Without predictions, the project's verdict says
its shape is not known (``ribbonctl project show``, ``GET /projects/{id}``); the predicted verdict
is tested on the page with a predicting daemon (tests/web/test_project_verdict_page.py).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from .conftest import own_printer
from .test_notify import Hook
from .test_projects import print_panel, ribbonctl, submit_project, wait_project

pytestmark = pytest.mark.timeout(360)


def test_the_last_panel_says_to_sew_the_seams_in_order(tmp_path: Path, meshes: dict[str, Path]) -> None:
    hook = Hook()
    try:
        with own_printer(tmp_path / "state", extra=f'[notify]\nurls = ["{hook.url}"]\ntimeout_s = 2\n') as (sim, daemon):
            api = daemon.client
            assert api is not None
            api.post("/printer/frame-ready")
            pid = submit_project(api, meshes["two_sided"], "2")["id"]
            p = wait_project(api, pid, lambda p: p["state"] not in ("submitted", "compiling"), timeout=240)
            assert p["panel_count"] == 2 and p["seams"], p
            assert p["reached"] is None and p["verdict"][0].startswith("reached: not known"), p["verdict"]
            shown = ribbonctl(daemon, "project", "show", pid)
            assert shown.returncode == 0 and "verdict     reached: not known" in shown.stdout, shown
            jobs = [q["job_id"] for q in p["panels"]]
            first = print_panel(api, sim, jobs[0])
            assert first["next"]["instruction"].startswith("done; print it again"), first["next"]
            wait_project(api, pid, lambda p: p["current_panel"] == 2 and p["state"] == "waiting")
            api.post("/printer/frame-ready")
            last = print_panel(api, sim, jobs[1])
            # the seams as project.json lists them, in that order
            order = ", ".join(f"{s['label']} (panels {s['panels'][0]} and {s['panels'][1]})" for s in p["seams"])
            assert last["next"]["instruction"].startswith("all 2 panels are printed: release them and sew seam"), last
            assert f"in this order: {order};" in last["next"]["instruction"], (order, last["next"])
            done = wait_project(api, pid, lambda p: p["state"] == "done")
            assert done["next"]["instruction"] == last["next"]["instruction"]
            deadline = time.monotonic() + 10
            while len([b for _, b in hook.got if b["title"].startswith("Done")]) < 2:
                assert time.monotonic() < deadline, [b["title"] for _, b in hook.got]
                time.sleep(0.05)
            dones = [b for _, b in hook.got if b["title"].startswith("Done")]
            assert "print it again" in dones[0]["message"] and "(all 2 panels)" not in dones[0]["title"]
            assert dones[1]["title"].startswith("Done (all 2 panels)"), dones[1]
            assert f"in this order: {order}" in dones[1]["message"] and "print it again" not in dones[1]["message"]
    finally:
        hook.close()
