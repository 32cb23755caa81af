"""The operator III on the page (issue 36 items 8 and 9), in headless chromium against a real ribbond
process and its own simulator: a head nobody homed shows "not homed" per axis (then its numbers once
homed); a job waiting for the flip shows what it waits for, no side printing and no time left."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.daemon.conftest import Daemon, Sim, own_printer, submit, wait_for

from .conftest import PHONE, shot

pytestmark = pytest.mark.timeout(240)

SECOND = 1000


@pytest.fixture
def printer(tmp_path: Path) -> Iterator[tuple[Sim, Daemon]]:
    with own_printer(tmp_path / "state") as pair:
        yield pair


def test_not_homed_and_a_wait_that_is_not_progress(browser_page: Any, printer: tuple[Sim, Daemon],
                                                   meshes: dict[str, Path]) -> None:
    sim, daemon = printer
    api = daemon.client
    assert api is not None
    page = browser_page()
    page.goto(daemon.url + "/")
    page.wait_for_function("() => document.querySelector('#p-position').textContent.includes('homed')",
                           timeout=30 * SECOND)
    assert page.text_content("#p-position") == "x not homed  y not homed  z not homed"
    assert "0.00" not in page.inner_text("#p-position")
    shot(page, "not-homed")
    assert api.post("/printer/home", timeout=330).status_code == 200
    page.wait_for_function("() => !document.querySelector('#p-position').textContent.includes('homed')",
                           timeout=30 * SECOND)
    text = page.inner_text("#p-position")
    assert text.startswith("x ") and text.endswith(" mm") and "not homed" not in text, text

    job = submit(api, meshes["two_sided"], start=True)
    wait_for(api, job, "awaiting_flip", timeout=120)
    phone = browser_page(PHONE)
    phone.goto(f"{daemon.url}/#/job/{job}")
    phone.wait_for_function("() => document.querySelector('#j-progress-text').textContent.includes('waiting for')",
                            timeout=30 * SECOND)
    progress = phone.inner_text("#j-progress-text")
    assert progress.startswith("waiting for the flip ·"), progress
    assert "left" not in progress and "back side" not in progress, progress
    shot(phone, "waiting-for-the-flip-phone")
    assert api.post(f"/jobs/{job}/cancel").status_code == 200
    assert not browser_page.errors, browser_page.errors
