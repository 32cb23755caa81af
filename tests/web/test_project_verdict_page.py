"""A project's verdict (issue 36 item 7) from ``ribbonctl submit --panels`` to the page, in headless
chromium against a real ribbond process that predicts in its compiles: the submit prints the
project's reached / not-reached line (the same lines as ``GET /projects/{id}``'s ``verdict``, made
by ``ribbond.design.verdict.project_verdict_lines``, whose rule tests/design/test_verdict.py checks);
the project page shows those lines and the sewn prediction (``deployed.png``, drawn: not blank)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from ribbond.design.verdict import project_reached
from tests.daemon.conftest import PARAMETERS, PREDICT, ROOT, Daemon, Sim, own_printer

from .conftest import PHONE, shot

pytestmark = pytest.mark.timeout(600)

SECOND = 1000


@pytest.fixture
def predicting(tmp_path: Path) -> Iterator[tuple[Sim, Daemon]]:
    with own_printer(tmp_path / "state", extra=PREDICT) as pair:
        yield pair


def test_the_project_verdict_and_the_sewn_prediction(browser_page: Any, predicting: tuple[Sim, Daemon],
                                                     meshes: dict[str, Path], tmp_path: Path) -> None:
    _, daemon = predicting
    api = daemon.client
    assert api is not None
    params = tmp_path / "params.json"
    params.write_text(json.dumps(PARAMETERS), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "--url", daemon.url, "submit",
                           str(meshes["two_sided"]), "--panels", "2", "--params", str(params)],
                          cwd=ROOT, capture_output=True, text=True, timeout=540)
    assert proc.returncode == 0, proc.stderr
    pid = next(p["id"] for p in api.get("/projects").json())
    p = api.get(f"/projects/{pid}").json()
    layout = api.get(f"/projects/{pid}/files/project.json").json()
    # the verdict follows project.json's predictions by the rule (checked in test_verdict.py)
    assert p["reached"] is project_reached(layout) and p["reached"] is not None, p
    assert p["verdict"][0].startswith("reached: yes: " if p["reached"] else "reached: NO: "), p["verdict"]
    for line in p["verdict"]:
        assert f"verdict     {line}" in proc.stdout, proc.stdout           # ribbonctl submit --panels prints them
    assert f"/projects/{pid}/files/deployed.png" in proc.stdout
    assert p["has_deployed"] and api.get(f"/projects/{pid}/files/deployed.png").content[:4] == b"\x89PNG"

    for name, viewport in (("project-verdict", None), ("project-verdict-phone", PHONE)):
        page = browser_page(viewport) if viewport else browser_page()
        page.goto(f"{daemon.url}/#/project/{pid}")
        page.wait_for_selector("#pj-verdict li", timeout=30 * SECOND)
        assert page.locator("#pj-verdict li").all_inner_texts() == p["verdict"]
        page.wait_for_function("() => { const i = document.querySelector('#pj-dimg'); "
                               "return i && i.complete && i.naturalWidth > 0; }", timeout=30 * SECOND)
        assert page.is_visible("#pj-dimg")
        # drawn, not blank: the picture has more than one colour
        colours = page.evaluate("""() => { const i = document.querySelector('#pj-dimg');
            const c = document.createElement('canvas'); c.width = i.naturalWidth; c.height = i.naturalHeight;
            const g = c.getContext('2d'); g.drawImage(i, 0, 0);
            const d = g.getImageData(0, 0, c.width, c.height).data; const seen = new Set();
            for (let k = 0; k < d.length; k += 4 * 97) seen.add(d[k] << 16 | d[k + 1] << 8 | d[k + 2]);
            return seen.size; }""")
        assert colours > 16, colours
        page.locator("#pj-prediction").scroll_into_view_if_needed()
        shot(page, name)
    assert not browser_page.errors, browser_page.errors
