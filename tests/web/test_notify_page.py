"""The dashboard's notifications line (issue 27, item 3) in headless chromium, on a phone's screen.

A daemon of its own (no printer: the line needs none) with two services on loopback: a JSON webhook
that answers and a port nothing listens on. The page is opened first ("none sent yet"); a test
message (``POST /notifications/test``, as ``ribbonctl notify test`` sends it) then reaches the line
over the event stream: the last sent, and the failure in red with Apprise's reason.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.daemon.conftest import Daemon
from tests.daemon.test_notify import Hook, refused_url

from .conftest import PHONE, SHOTS

pytestmark = pytest.mark.timeout(120)

SECOND = 1000                                            # Playwright's timeouts are in ms


def test_the_notifications_line_shows_the_last_sent_and_the_failure(browser_page: Any, tmp_path: Path) -> None:
    hook, refused = Hook(), refused_url()
    daemon = Daemon(tmp_path / "state", str(tmp_path / "no-printer"),
                    extra=f'[notify]\nurls = ["{hook.url}", "{refused}"]\ntimeout_s = 2\n')
    try:
        daemon.start()
        assert daemon.client is not None
        page = browser_page(PHONE)
        page.goto(daemon.url + "/")
        page.wait_for_selector("#live:text('live')", timeout=20 * SECOND)
        page.wait_for_selector("#notify-line:has-text('none sent yet')", timeout=10 * SECOND)

        r = daemon.client.post("/notifications/test")
        assert r.status_code == 202 and r.json()["urls"] == [hook.url, refused]
        page.wait_for_selector("#notify-line .error", timeout=10 * SECOND)
        page.wait_for_selector("#notify-line:has-text('last sent')", timeout=10 * SECOND)
        line = page.locator("#notify-line").inner_text()
        assert "“ribbond: test notification”" in line and "failed" in line and refused in line, line
        assert "Connection error" in page.locator("#notify-line .error").inner_text(), line
        assert len(hook.got) == 1 and hook.got[0][1]["title"] == "ribbond: test notification"
        width = page.evaluate("document.documentElement.scrollWidth")
        assert width <= PHONE["width"], f"the page is {width} px wide on a {PHONE['width']} px screen"
        page.locator("#printer").screenshot(path=str(SHOTS / "20-phone-notifications.png"))
        assert not browser_page.errors, browser_page.errors
    finally:
        daemon.stop()
        hook.close()
