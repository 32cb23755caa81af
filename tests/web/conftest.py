"""Fixtures of the dashboard's browser tests: headless Debian chromium driven by Playwright, against
a real ribbond process and the simulator (the daemon tests' helpers, imported, not copied)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.daemon.conftest import ROOT, api, meshes, shared_daemon, shared_sim  # noqa: F401 (fixtures)

CHROMIUM = os.environ.get("RIBBOND_CHROMIUM", "/usr/bin/chromium")
#: Without these chromium tries to reach the network (updates, field trials) from an empty profile.
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--no-first-run"]
SHOTS = ROOT / "out" / "dashboard"
DESKTOP = {"width": 1280, "height": 900}
PHONE = {"width": 390, "height": 844}


# Module scope: Playwright's sync API keeps an event loop running in this thread while it is open,
# and the asyncio tests a pytest-xdist worker runs after a web module would find it.
@pytest.fixture(scope="module")
def playwright() -> Iterator[Any]:
    if not Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} is missing: `make test` installs Debian's chromium (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    SHOTS.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        yield p


@pytest.fixture(scope="module")
def chromium(playwright: Any) -> Iterator[Any]:
    """One chromium per test module (its start is a second or more on a loaded machine); each page
    gets a context of its own, which starts as empty as a fresh profile (storage, cookies, cache)."""
    browser = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
    try:
        yield browser
    finally:
        browser.close()


@pytest.fixture
def browser_page(chromium: Any) -> Iterator[Any]:
    """``open(viewport)`` gives a page in a new browser context: no storage, cookies or cache of
    an earlier page or test."""
    contexts: list[Any] = []

    def open_page(viewport: dict[str, int] = DESKTOP) -> Any:
        context = chromium.new_context(viewport=viewport, device_scale_factor=1, accept_downloads=False)
        context.set_default_timeout(30_000)
        contexts.append(context)
        page = context.new_page()
        page.on("pageerror", lambda e: errors.append(str(e)))
        return page

    errors: list[str] = []
    open_page.errors = errors  # type: ignore[attr-defined]
    try:
        yield open_page
    finally:
        for context in contexts:
            context.close()


def shot(page: Any, name: str, full_page: bool = True) -> Path:
    """A screenshot of the page in out/dashboard/ (looked at by people: keep the page clear)."""
    path = SHOTS / f"{name}.png"
    if full_page:
        page.evaluate("window.scrollTo(0, 0)")           # else the sticky bar is drawn mid-page
    page.screenshot(path=str(path), full_page=full_page)
    return path
