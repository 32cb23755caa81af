"""A project on the page (issue 26), in headless chromium against a real ribbond process and the
simulator: the submit form's panels field, the panel map drawn from project.json's outlines and
coloured by each panel's state, the operator's step between panels ("panel 2 of 3: load a fresh
stretched fabric") and its button, on a desktop and on a phone; cancelling the project from the page."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.daemon.conftest import Daemon, Sim, wait_for
from tests.daemon.test_projects import print_panel, wait_project

from .conftest import PHONE, shot

pytestmark = pytest.mark.timeout(240)

SECOND = 1000


def panel_classes(page: Any) -> list[str]:
    """Each panel's colour class in the drawn map, by panel."""
    return page.eval_on_selector_all(
        "#pj-map .panel", "gs => gs.map(g => g.getAttribute('class').split(' ')[1])")


def test_the_panel_map_and_the_step_between_panels(browser_page: Any, shared_daemon: Daemon, shared_sim: Sim,
                                                   api: httpx.Client, meshes: dict[str, Path]) -> None:
    page = browser_page()
    page.goto(shared_daemon.url + "/")
    page.set_input_files("#file", str(meshes["two_sided"]))
    page.fill("#size", "70")
    assert "largest the frame and the plastic allow" in page.get_attribute("#size", "placeholder")
    page.select_option("#panels", "3")
    assert page.is_visible("#seam_allowance")
    assert "own units" in page.get_attribute("#size", "placeholder")    # a project keeps the mesh's scale
    page.check("#start-now")
    page.click("#submit-btn")
    page.wait_for_url("**/#/project/prj-*", timeout=30 * SECOND)
    pid = page.url.rsplit("/", 1)[1]
    p = wait_project(api, pid, lambda p: p["panel_count"] == 3)
    page.wait_for_selector("#pj-map .panel", timeout=30 * SECOND)
    assert page.locator("#pj-map .panel").count() == 3
    assert page.locator("#pj-map .panel text").all_text_contents() == ["1", "2", "3"]
    print_panel(api, shared_sim, p["panels"][0]["job_id"])             # panel 1: front, flip, alignment, back
    wait_project(api, pid, lambda p: p["current_panel"] == 2 and p["state"] == "waiting")
    page.wait_for_function("() => document.querySelector('#pj-next').textContent.startsWith('panel 2 of 3')",
                           timeout=30 * SECOND)
    assert page.inner_text("#pj-next").startswith("panel 2 of 3: load a fresh stretched frame")
    assert panel_classes(page) == ["done", "waiting", "queued"]
    assert page.is_visible("text=Fresh frame loaded (panel 2)")
    shot(page, "project-between-panels")
    home = browser_page()
    home.goto(shared_daemon.url + "/")
    home.wait_for_selector("#project-cards .panelmap", timeout=30 * SECOND)
    assert "panel 2 of 3: load a fresh stretched frame" in home.inner_text("#needs-you").lower() \
        or "load a fresh stretched frame" in home.inner_text("#project-cards")
    shot(home, "project-home-card")
    phone = browser_page(PHONE)
    phone.goto(f"{shared_daemon.url}/#/project/{pid}")
    phone.wait_for_selector("#pj-map .panel.waiting", timeout=30 * SECOND)
    width = phone.evaluate("() => document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the page is {width} px wide on a {PHONE['width']} px phone"
    shot(phone, "project-between-panels-phone")
    # the operator loads the fabric and says so on the page: panel 2 prints
    shared_sim.ensure_front()
    page.click("text=Fresh frame loaded (panel 2)")
    job2 = p["panels"][1]["job_id"]
    wait_for(api, job2, {"printing_front", "awaiting_flip"}, timeout=60, fresh_frame=False)
    page.wait_for_function("() => document.querySelector('#pj-map .panel.now.printing, #pj-map .panel.now.waiting')",
                           timeout=30 * SECOND)
    shot(page, "project-panel-2-printing")
    # cancelling the project from the page cancels what is left
    page.on("dialog", lambda d: d.accept())
    page.click("text=Cancel the project")
    wait_project(api, pid, lambda p: p["state"] == "cancelled")
    page.wait_for_function("() => document.querySelectorAll('#pj-map .panel.stopped').length === 2",
                           timeout=30 * SECOND)
    assert panel_classes(page) == ["done", "stopped", "stopped"]
    assert "ribbonctl project start" in page.inner_text("#pj-next")
    shot(page, "project-cancelled")
    assert not browser_page.errors, browser_page.errors
