"""The dashboard's G-code console (issue 22, item 2) in headless chromium: a command that would
drive the nozzle into the fabric is refused with the daemon's reason and nothing runs; a fast Z
move runs clamped, the page showing what was sent and the note."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx

from ribbond.gcode.profiles import load_profile
from tests.daemon.conftest import Daemon, Sim

SECOND = 1000
PROFILE = load_profile("ultimaker2-tpu")
SHOTS = Path("/work/shots")


def test_the_console_shows_refusals_and_clamped_feeds(browser_page: Any, shared_daemon: Daemon, shared_sim: Sim,
                                                      api: httpx.Client) -> None:
    assert api.post("/printer/home").status_code == 200
    cx, cy = PROFILE.frame.center
    assert api.post("/printer/goto", json={"x": cx, "y": cy}).status_code == 200
    page = browser_page()
    page.goto(shared_daemon.url + "/")
    page.wait_for_selector("#conn.ready", timeout=20 * SECOND)
    before = shared_sim.program_commands()
    page.fill("#console-in", "G1 Z-2 F600")
    page.press("#console-in", "Enter")
    page.wait_for_selector("#console-out .error:text('below the fabric')")
    assert "command 1 (G1 Z-2 F600)" in page.inner_text("#console-out .error")
    assert shared_sim.program_commands() == before
    page.fill("#console-in", "G1 Z15 F6000")
    page.press("#console-in", "Enter")
    z_feed = PROFILE.motion.max_z_speed * 60
    page.wait_for_selector(f"#console-out .note:text('sent as: G1 Z15 F{z_feed:g}')")
    page.wait_for_selector("#console-out .note:text('feed rate clamped to the profile')")
    assert shared_sim.program_commands()[len(before):] == ["G90", f"G1 Z15 F{z_feed:g}"]
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.evaluate("window.scrollTo(0, 0)")               # else the sticky bar is drawn mid-page
    page.screenshot(path=str(SHOTS / "h2-console-refused-and-clamped.png"), full_page=True)
    assert not browser_page.errors, browser_page.errors
