"""The prediction on a job's page (issue 23 items 3 and 4), in headless chromium on a phone's
viewport against a real ribbond: whether the target is reached first (red when not), then the
verdict, the total Gaussian curvature, the area ratio, the spread, and the mean deviation last; an
older (format 2) report still shown, with a note; "Predict again" runs POST /jobs/{id}/predict with
its progress shown, and the card then shows the new report."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.daemon.conftest import PREDICT, Daemon, submit, wait_for

from .conftest import PHONE, shot

#: The shared daemon predicts in its compiles (the harness turns that off elsewhere).
DAEMON_EXTRA = PREDICT

pytestmark = pytest.mark.timeout(240)

SECOND = 1000
ORDER = ["Total Gaussian curvature", "Area, predicted / target", "Spread over releases",
         "Deviation from the target", "Model"]


def no_sideways_scroll(page: Any) -> None:
    width = page.evaluate("document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the page is {width} px wide on a {PHONE['width']} px phone"


def test_an_older_report_shows_and_predict_again_replaces_it(
        browser_page: Any, shared_daemon: Daemon, api: httpx.Client, meshes: dict[str, Path]) -> None:
    job = submit(api, meshes["two_sided"], start=False)
    wait_for(api, job, "ready", timeout=120)
    old = api.get(f"/jobs/{job}/files/design.json").json()["report"]["deployed"]
    page = browser_page(PHONE)
    page.goto(f"{shared_daemon.url}/#/job/{job}")
    page.wait_for_selector("#j-prediction:not([hidden])", timeout=30 * SECOND)
    if "reached" not in old:                           # a format 2 report: no verdict of its own, a note
        assert page.locator("#pr-reached").is_hidden() and page.locator("#pr-old").is_visible()
    facts = page.locator("#pr-facts dt").all_inner_texts()
    assert facts[-2:] == ORDER[-2:]
    assert f"{old['deviation_pct']['mean']:.1f} % mean" in page.inner_text("#pr-facts")
    assert "Deployed shape" not in page.inner_text("#j-summary")          # not a headline any more
    assert "%" not in page.inner_text("#cap-deployed")
    no_sideways_scroll(page)

    page.click("#pr-run")
    page.wait_for_selector("#pr-progress:not([hidden])", timeout=10 * SECOND)
    shot(page, "23-predicting-phone", full_page=False)
    page.wait_for_selector("#pr-progress", state="hidden", timeout=120 * SECOND)
    record = api.get(f"/jobs/{job}").json()
    assert record["prediction"]["state"] == "done", record["prediction"]
    new = api.get(f"/jobs/{job}/files/design.json").json()["report"]["deployed"]
    assert new["time_s"] != old["time_s"]                              # a new prediction was written
    page.wait_for_function(f"document.querySelector('#pr-facts').innerText.includes('{new['time_s']:.1f} s')",
                           timeout=30 * SECOND)
    assert page.locator("#pr-error").is_hidden()
    assert not browser_page.errors, browser_page.errors


def format3(deployed: dict[str, Any]) -> dict[str, Any]:
    """A format 3 ``report.deployed`` of a layout that misses its target (the issue's bowl)."""
    return {**deployed, "total_gaussian_curvature": {"predicted": 0.31, "target": 4.3}, "area_ratio": 0.913,
            "spread": {"mean": [1.9, 2.4], "max": [6.0, 7.5], "releases": 5}, "reached": False,
            "verdict": "rolls into the bowl's volume but keeps 7 % of its curvature: this layout will not take "
                       "the target's shape", "model": "homogenized"}


def test_a_format3_report_leads_with_whether_the_target_is_reached(
        browser_page: Any, shared_daemon: Daemon, api: httpx.Client, meshes: dict[str, Path]) -> None:
    job = submit(api, meshes["one_sided"], start=False)
    record = wait_for(api, job, "ready", timeout=120)
    path = Path(record["design_dir"]) / "design.json"
    design = json.loads(path.read_text())
    design["report"]["deployed"] = d = format3(design["report"]["deployed"])
    path.write_text(json.dumps(design))                # as the engine of issue 23 writes it
    page = browser_page(PHONE)
    page.goto(f"{shared_daemon.url}/#/job/{job}")
    page.wait_for_selector("#pr-reached:not([hidden])", timeout=30 * SECOND)
    assert page.inner_text("#pr-reached") == "Will NOT take the target's shape"
    colour = page.locator("#pr-reached").evaluate("e => getComputedStyle(e).color")
    danger = page.evaluate("getComputedStyle(document.documentElement).getPropertyValue('--danger').trim()")
    h = danger.lstrip("#")
    assert colour == f"rgb({int(h[0:2], 16)}, {int(h[2:4], 16)}, {int(h[4:6], 16)})", (colour, danger)
    assert page.inner_text("#pr-line") == d["verdict"]
    assert page.locator("#pr-facts dt").all_inner_texts() == ORDER
    values = page.locator("#pr-facts dd").all_inner_texts()
    assert values[0] == "0.31 predicted, 4.30 target"
    assert values[1] == "0.913"
    assert values[2] == "mean 1.9–2.4 %, max 6.0–7.5 % (5 releases)"
    assert values[3].startswith(f"{d['deviation_pct']['mean']:.1f} % mean")
    # the order on the page: reached, the verdict, the figures (the mean deviation among the last)
    ys = [page.locator(s).bounding_box()["y"] for s in ("#pr-reached", "#pr-line", "#pr-facts")]
    assert ys == sorted(ys)
    assert page.locator("#pr-old").is_hidden()
    assert "does NOT take" in page.inner_text("#cap-deployed")
    no_sideways_scroll(page)
    page.locator("#j-prediction").scroll_into_view_if_needed()
    shot(page, "23-prediction-phone", full_page=False)
    assert not browser_page.errors, browser_page.errors
