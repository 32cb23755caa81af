"""The camera on the dashboard (issue 27), in headless chromium against a real ribbond whose
``[camera]`` is the simulator's own camera (``python -m sim --camera-port 0``), behind a token.

The camera's card appears while a job prints (under the job's card; on the home page under the
printer's) and while its back is aligned (in the alignment step, beside the jog pad), its <img>
showing frames read through the daemon with the token in the header; it is hidden otherwise. The
snapshot kept at the end of the print is shown in the job's view. Screenshots of each go to
out/dashboard/camera-*.png (desktop and phone width).
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.daemon.conftest import TIME_SCALE, Daemon, cancel_leftovers, frame_ready, running, submit, wait_for
from tests.daemon.test_camera import SMALL, CameraSim, camera_table

from .conftest import DESKTOP, PHONE, shot

pytestmark = pytest.mark.timeout(240)

SECOND = 1000
TOKEN = "camera-page-token"
#: Where the screenshots the issue asks for go (besides out/dashboard/).
ISSUE_SHOTS = Path("/work/shots")
#: The camera's card shows frames: visible, its image decoded (naturalWidth > 0), a few frames in.
SHOWING = """() => { const card = document.querySelector('#camera'), img = document.querySelector('#camera-img');
  return !card.hidden && img.naturalWidth > 0 && Number(img.dataset.frames || 0) >= 3; }"""


@pytest.fixture(scope="module")
def watched(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[CameraSim, Daemon]]:
    """A simulator with its camera (at the harness's speed: a print lasts long enough to look at)
    and a daemon with a token whose camera it is."""
    sim = CameraSim(TIME_SCALE)
    try:
        with running(tmp_path_factory.mktemp("ribbond-camera"), sim.port, api=f'token = "{TOKEN}"',
                     extra=camera_table(sim.camera + "stream", sim.camera + "snapshot"), token=TOKEN) as daemon:
            yield sim, daemon
    finally:
        sim.stop()


def spiral(tmp_path: Path) -> Path:
    """A plain program: heat, then a square spiral of beads around the frame's centre (about 7 s here)."""
    lines = ["G28", "M104 S210", "M109 S210", "G90", "M83", "G0 X106 Y106 Z0.3 F3000"]
    x = y = 106.0
    for i in range(46):
        step = 4.0 + 2.0 * i
        dx, dy = [(step, 0), (0, step), (-step, 0), (0, -step)][i % 4]
        x, y = x + dx, y + dy
        lines.append(f"G1 X{x:.1f} Y{y:.1f} E{abs(dx + dy) * 0.03:.3f} F900")
    path = tmp_path / "spiral.gcode"
    path.write_text("\n".join([*lines, "G0 Z10", "M104 S0"]) + "\n", encoding="utf-8")
    return path


def open_page(browser_page: Any, daemon: Daemon, viewport: dict[str, int], where: str) -> Any:
    page = browser_page(viewport)
    page.context.add_init_script(f"localStorage.setItem('ribbond.token', '{TOKEN}')")
    page.goto(f"{daemon.url}/#{where}")
    page.wait_for_selector("#live.ready", timeout=20 * SECOND)
    return page


def keep_shot(page: Any, name: str, full_page: bool = True) -> None:
    path = shot(page, name, full_page)
    if ISSUE_SHOTS.parent.exists():
        ISSUE_SHOTS.mkdir(exist_ok=True)
        shutil.copy(path, ISSUE_SHOTS / path.name)


def test_the_camera_is_shown_while_printing_and_aligning_and_its_snapshot_with_the_job(
        browser_page: Any, watched: tuple[CameraSim, Daemon], meshes: dict[str, Path], tmp_path: Path) -> None:
    sim, daemon = watched
    api = daemon.client
    assert api is not None
    frame_ready(api)
    with spiral(tmp_path).open("rb") as f:
        program = api.post("/jobs", files={"gcode": ("spiral.gcode", f)}, data={"start": "false"}).json()["id"]
    desktop = open_page(browser_page, daemon, DESKTOP, f"/job/{program}")
    phone = open_page(browser_page, daemon, PHONE, f"/job/{program}")
    assert desktop.locator("#camera").is_hidden() and phone.locator("#camera").is_hidden()   # ready: no camera

    assert api.post(f"/jobs/{program}/start").status_code == 200
    design = submit(api, meshes["two_sided"], start=True, parameters=SMALL)   # compiles meanwhile; prints next
    for page in (desktop, phone):
        page.wait_for_function(SHOWING, timeout=30 * SECOND)
    wait_for(api, program, "printing_front", until=lambda j: j["progress"] > 0.5, timeout=60)
    for page in (desktop, phone):
        page.wait_for_function(SHOWING.replace(">= 3", ">= 10"), timeout=10 * SECOND)   # still streaming
    keep_shot(desktop, "camera-printing-desktop")
    keep_shot(phone, "camera-printing-phone")
    # the camera comes right under the job's card, above its pictures
    assert desktop.evaluate("document.querySelector('#jobpage > section.card').nextElementSibling.id") == "camera"
    desktop.evaluate("location.hash = '#/'")
    desktop.wait_for_function(SHOWING, timeout=10 * SECOND)
    assert desktop.evaluate("document.querySelector('#printer').nextElementSibling.id") == "camera"
    keep_shot(desktop, "camera-home-desktop")

    # done: the camera goes away, the snapshot of the program's end is in the job's view
    wait_for(api, program, "done", timeout=60)
    phone.wait_for_selector("#camera", state="hidden", timeout=10 * SECOND)
    phone.wait_for_function("(() => { const i = document.querySelector('#j-snaps img'); "
                            "return i && i.naturalWidth > 0; })()", timeout=20 * SECOND)
    assert "The program, printed" in phone.locator("#j-snapshots figcaption").inner_text()
    keep_shot(phone, "camera-snapshot-phone")

    # the design: its front, the flip, and the alignment with the camera beside the jog pad
    wait_for(api, design, "awaiting_flip", timeout=120)
    sim.flip(0.4, -0.3, 0.6)
    assert api.post(f"/jobs/{design}/flip-done").status_code == 200
    wait_for(api, design, "aligning", until=lambda j: j["waits_for_operator"], timeout=30)
    phone.evaluate(f"location.hash = '#/job/{design}'")
    phone.wait_for_function(SHOWING, timeout=20 * SECOND)
    assert phone.evaluate("document.querySelector('#camera').parentElement.id") == "align-camera"
    # what the phone's screen shows: the step scrolled into view, the camera above the jog pad
    phone.wait_for_function("document.querySelector('#align').getBoundingClientRect().top < 120")
    assert phone.evaluate("document.querySelector('#align-here').getBoundingClientRect().bottom") < PHONE["height"]
    keep_shot(phone, "camera-aligning-phone", full_page=False)
    cancel_leftovers(api)
    sim.ensure_front()
