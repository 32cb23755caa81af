"""The dashboard's "Adjust the print" panel (issue 36, item 10) in headless chromium, while a plain
G-code job streams to the simulator: an out-of-limit speed is refused with the daemon's reason and
never reaches the printer; a speed within the profile's range is sent beside the program and the
panel shows the speed the printer reports back (M220); the console takes M105 and refuses a move."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import httpx

from ribbond.gcode.profiles import load_profile
from tests.daemon.conftest import Daemon, Sim
from tests.daemon.test_adjust import start_program, wait_moving, zigzag
from tests.web.conftest import DESKTOP, PHONE, shot

SECOND = 1000
PROFILE = load_profile("ultimaker2-tpu")
LOW, HIGH = PROFILE.adjust.speed_percent


def test_the_adjust_panel_sets_the_speed_of_a_running_print(browser_page: Any, shared_daemon: Daemon,
                                                            shared_sim: Sim, api: httpx.Client,
                                                            tmp_path: Path) -> None:
    zigzag(tmp_path / "long.gcode", moves=600)              # ~25 s on the simulator: time to click
    since = len(shared_sim.commands())
    job = start_program(api, tmp_path / "long.gcode")
    wait_moving(api, shared_sim, job, since)
    page = browser_page(PHONE)
    page.goto(shared_daemon.url + "/")
    page.wait_for_selector("#adjust:not([hidden]) .adjust-when:text('Adjusts the print of')", timeout=20 * SECOND)
    assert page.get_attribute("#adj-speed", "max") == f"{HIGH:g}"

    page.fill("#adj-speed", "500")
    page.click("#adjust button[data-key=speed]")
    page.wait_for_selector(f"#adjust .adjust-out.error:text('feed override above {HIGH:g} %')")
    assert not [c for c in shared_sim.commands()[since:] if c["command"].startswith("M220 S500")]

    page.fill("#adj-speed", "60")
    page.click("#adjust button[data-key=speed]")
    page.wait_for_selector("#adjust .adjust-out:text('beside job')")
    page.wait_for_selector("#adjust .adjust-now:text('Speed 60 % · flow 100 %')")
    assert "M220 S60" in [c["command"] for c in shared_sim.commands()[since:]]

    page.fill("#console-in", "G1 X100 Y100")
    page.press("#console-in", "Enter")
    page.wait_for_selector("#console-out .error:text('not accepted while a program prints')")
    page.fill("#console-in", "M105")
    page.press("#console-in", "Enter")
    page.wait_for_selector("#console-out .answer:text('T:')")
    # its answer, not the program lines' acknowledgements that came meanwhile
    assert not [line for line in page.locator("#console-out .answer").all_inner_texts() if line.startswith("ok N")]
    assert api.get(f"/jobs/{job}").json()["state"] == "printing_front"
    page.locator("#adjust").scroll_into_view_if_needed()
    shot(page, "adjust-phone-390", full_page=False)
    page.set_viewport_size(DESKTOP)
    shot(page, "adjust-desktop-1280")
    assert not browser_page.errors, browser_page.errors

    assert api.post(f"/jobs/{job}/cancel").status_code == 200
    deadline = time.monotonic() + 30
    while api.get(f"/jobs/{job}").json()["state"] != "cancelled" and time.monotonic() < deadline:
        time.sleep(0.1)
    assert api.post("/printer/adjust", json={"speed": 100}).status_code == 200
