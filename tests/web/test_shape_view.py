"""The predicted shape in 3D on a job's page (issue 36 item 11), in headless chromium against a real
ribbond that predicts: the target and the prediction drawn with WebGL at 1280 px and 390 px (the
screenshots out/dashboard/36-shape-3d-*.png), turned by a drag and zoomed by the wheel and by a pinch
(the pixels change), the colours' legend, the verdict beside the view; GET /jobs/{id}/deviation against
the report's own figures; the design's meshes and previews to download; no request of the page fails
(the favicon); a design predicted not to take its shape says so beside "Print"."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from PIL import Image

from ribbond.mesh.files import read_mesh
from tests.daemon.conftest import PREDICT, Daemon, submit, wait_for

from .conftest import DESKTOP, PHONE, shot
from .test_prediction_card import format3, no_sideways_scroll

DAEMON_EXTRA = PREDICT

pytestmark = pytest.mark.timeout(300)

SECOND = 1000


def pixels(page: Any) -> np.ndarray:
    """The 3D view's canvas as drawn on the page, (h, w, 3) uint8."""
    png = page.locator("#shape-canvas").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def drawn(img: np.ndarray) -> np.ndarray:
    """The pixels that are not the canvas's white background, (h, w) bool."""
    return np.abs(img.astype(int) - 255).sum(axis=2) > 24


def extent(img: np.ndarray) -> tuple[int, int]:
    """The width and height of the box around the drawn pixels."""
    ys, xs = np.nonzero(drawn(img))
    return int(xs.max() - xs.min()), int(ys.max() - ys.min())


def viridis_share(img: np.ndarray) -> float:
    """The share of drawn pixels whose hue is viridis's (blue-violet through green to yellow, never red):
    the deviation's colours, not the grey target's."""
    px = img[drawn(img)].astype(float)
    r, g, b = px[:, 0], px[:, 1], px[:, 2]
    coloured = (np.max(px, axis=1) - np.min(px, axis=1)) > 40
    return float(np.mean(coloured & (r < g + 40) & ~((r > b) & (b > g))))


@pytest.fixture(scope="module")
def predicted(shared_daemon: Daemon, meshes: dict[str, Path]) -> dict[str, Any]:
    """A two-sided design compiled with its prediction (the job ready, not started)."""
    client = shared_daemon.client
    assert client is not None
    job = submit(client, meshes["two_sided"], start=False)
    return wait_for(client, job, "ready", timeout=180)


def test_the_deviation_per_vertex_is_the_reports_measure(api: httpx.Client, predicted: dict[str, Any]) -> None:
    job = predicted["id"]
    report = api.get(f"/jobs/{job}/files/design.json").json()["report"]["deployed"]
    r = api.get(f"/jobs/{job}/deviation")
    assert r.status_code == 200, r.text
    dev = r.json()
    V, _ = read_mesh(Path(predicted["design_dir"]) / "deployed.obj")
    T, _ = read_mesh(Path(predicted["design_dir"]) / "target.obj")
    assert dev["vertices"] == len(V) == len(dev["distance_mm"])
    assert dev["diagonal_mm"] == pytest.approx(float(np.linalg.norm(T.max(0) - T.min(0))), rel=1e-12)
    pct = 100 * np.asarray(dev["distance_mm"]) / dev["diagonal_mm"]
    # deployed.obj is written to 9 significant digits: the measure of the file is the report's to 1e-6
    for key, value in (("mean", pct.mean()), ("p99", np.percentile(pct, 99)), ("max", pct.max())):
        assert value == pytest.approx(report["deviation_pct"][key], rel=1e-6, abs=1e-9), key
    assert api.get("/jobs/000000000000/deviation").status_code == 404


def look_at_the_shape(page: Any, url: str, job: str) -> None:
    page.goto(f"{url}/#/job/{job}")
    page.wait_for_selector("#j-shape:not([hidden])", timeout=30 * SECOND)
    page.locator("#j-shape").scroll_into_view_if_needed()
    page.wait_for_function("Number(document.querySelector('#shape-canvas').dataset.frames || 0) > 0 && "
                           "document.querySelector('#shape-legend').innerText.includes('%')", timeout=30 * SECOND)
    page.wait_for_timeout(300)


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_shape_is_drawn_in_3d_and_turns_and_zooms(browser_page: Any, shared_daemon: Daemon, api: httpx.Client,
                                                      predicted: dict[str, Any], viewport: dict[str, int]) -> None:
    job = predicted["id"]
    page = browser_page(viewport)
    failed: list[str] = []
    page.on("response", lambda r: failed.append(f"{r.status} {r.url}") if r.status >= 400 else None)
    look_at_the_shape(page, shared_daemon.url, job)
    name = "desktop" if viewport is DESKTOP else "phone"
    shot(page, f"36-shape-3d-{name}", full_page=False)

    first = pixels(page)
    h, w, _ = first.shape
    assert w >= 0.8 * min(viewport["width"] - 60, 700) and h >= 0.6 * w, (w, h)    # not a thumbnail
    share = drawn(first).mean()
    assert 0.08 < share < 0.95, f"{share:.1%} of the canvas drawn"
    # side by side: the target grey (left, or above on a phone), the prediction in the deviation's colours
    half = w // 2 if viewport is DESKTOP else h // 2
    target, prediction = (first[:, :half], first[:, half:]) if viewport is DESKTOP else (first[:half], first[half:])
    assert drawn(target).mean() > 0.05 and drawn(prediction).mean() > 0.05
    assert viridis_share(target) < 0.05, "the target is not grey"
    assert viridis_share(prediction) > 0.5, "the prediction is not coloured by its deviation"
    labels = page.locator("#shape-labels span").all_inner_texts()
    assert labels == ["target", "prediction"], labels
    assert len(np.unique(first.reshape(-1, 3) // 8, axis=0)) > 50                    # shaded, not flat

    # beside it: the verdict, the figures and the legend's scale (deployed.png's: the p99, at least 0.5 %)
    d = api.get(f"/jobs/{job}/files/design.json").json()["report"]["deployed"]
    if "reached" in d:
        assert page.inner_text("#shape-reached") == ("Will take the target's shape" if d["reached"]
                                                     else "Will NOT take the target's shape")
        assert page.inner_text("#shape-verdict") == d["verdict"]
    assert f"{d['deviation_pct']['mean']:.1f} % mean" in page.inner_text("#shape-figures")
    top = max(d["deviation_pct"]["p99"], 0.5)
    assert page.locator("#shape-legend .ticks span").last.inner_text() == f"{top:.1f} %"
    if viewport is DESKTOP:                               # beside: the verdict right of the view
        view, side = page.locator("#shape-canvas").bounding_box(), page.locator(".shape-side").bounding_box()
        assert side["x"] >= view["x"] + view["width"] and side["y"] < view["y"] + view["height"]

    # a drag turns it
    box = page.locator("#shape-canvas").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 90, cy + 40, steps=8)
    page.mouse.up()
    page.wait_for_timeout(200)
    turned = pixels(page)
    assert np.mean(np.any(turned != first, axis=2)) > 0.05, "a drag did not turn the view"
    # the wheel zooms in: the shape covers more of the canvas
    page.mouse.move(cx, cy)
    page.mouse.wheel(0, -400)
    page.wait_for_timeout(200)
    zoomed = pixels(page)
    assert drawn(zoomed).mean() > 1.3 * drawn(turned).mean()
    # the buttons: the target alone is grey (no deviation colours), Reset gives the first view back
    page.click("#shape-modes button[data-mode=target]")
    page.wait_for_timeout(200)
    assert viridis_share(pixels(page)) < 0.05
    page.click("#shape-modes button[data-mode=deployed]")
    page.wait_for_timeout(200)
    alone = pixels(page)
    assert viridis_share(alone) > 0.5
    page.click("#shape-modes button[data-mode=both]")                     # overlaid: the target's edges over it
    page.wait_for_timeout(200)
    overlaid = pixels(page)
    assert viridis_share(overlaid) > 0.3 and np.mean(np.any(overlaid != alone, axis=2)) > 0.05
    page.click("#shape-modes button[data-mode=side]")
    page.click("#shape-modes button[data-mode=reset]")
    page.wait_for_timeout(200)
    assert np.mean(np.any(pixels(page) != first, axis=2)) < 0.01
    if viewport is PHONE:
        no_sideways_scroll(page)
    assert not failed, failed                                              # the favicon included
    assert not browser_page.errors, browser_page.errors


def test_a_pinch_zooms_on_a_phone(browser_page: Any, shared_daemon: Daemon, api: httpx.Client,
                                  predicted: dict[str, Any]) -> None:
    page = browser_page(PHONE)
    look_at_the_shape(page, shared_daemon.url, predicted["id"])
    before = pixels(page)
    box = page.locator("#shape-canvas").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    cdp = page.context.new_cdp_session(page)

    def touch(kind: str, spread: float) -> None:
        points = [] if kind == "touchEnd" else [{"x": cx - spread, "y": cy, "id": 1}, {"x": cx + spread, "y": cy, "id": 2}]
        cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})

    touch("touchStart", 20)
    for s in range(25, 125, 10):                                          # two fingers move apart
        touch("touchMove", s)
    touch("touchEnd", 0)
    page.wait_for_timeout(300)
    after = pixels(page)
    assert drawn(after).mean() > 1.3 * drawn(before).mean(), "a pinch did not zoom in"
    assert not browser_page.errors, browser_page.errors


def test_the_design_files_download_and_the_favicon_is_served(browser_page: Any, shared_daemon: Daemon,
                                                            api: httpx.Client, predicted: dict[str, Any]) -> None:
    job = predicted["id"]
    page = browser_page(DESKTOP)
    look_at_the_shape(page, shared_daemon.url, job)
    links = page.locator("#j-files a").all_inner_texts()
    for name in ("target.obj", "deployed.obj", "preview.png", "preview.svg", "deployed.png", "design.json"):
        assert name in links, links
        href = page.locator(f"#j-files a[data-file='{name}']").get_attribute("href")
        r = api.get(href)
        assert r.status_code == 200 and r.content == (Path(predicted["design_dir"]) / name).read_bytes(), name
    icon = api.get("/favicon.ico")
    assert icon.status_code == 200 and icon.headers["content-type"].startswith("image/svg+xml")
    assert page.evaluate("document.querySelector('link[rel=icon]').href").endswith("/ui/favicon.svg")
    assert api.get("/ui/favicon.svg").status_code == 200


def test_print_on_a_design_that_misses_its_shape_says_so_beside_the_button(
        browser_page: Any, shared_daemon: Daemon, api: httpx.Client, meshes: dict[str, Path]) -> None:
    job = submit(api, meshes["one_sided"], start=False)
    record = wait_for(api, job, "ready", timeout=180)
    path = Path(record["design_dir"]) / "design.json"
    design = json.loads(path.read_text())
    design["report"]["deployed"] = d = format3(design["report"]["deployed"])
    path.write_text(json.dumps(design))                # a layout that misses its target (the engine's verdict)
    page = browser_page(PHONE)
    page.goto(f"{shared_daemon.url}/#/job/{job}")
    page.wait_for_selector("#print-warning", timeout=30 * SECOND)
    assert page.inner_text("#j-next") == "Ready to print: press Print."
    warning = page.inner_text("#print-warning")
    assert warning.startswith("Predicted NOT to take the target's shape") and d["verdict"] in warning
    button = page.locator("#j-actions button[data-action=start]").bounding_box()
    beside = page.locator("#print-warning").bounding_box()
    assert abs(beside["y"] - (button["y"] + button["height"])) < 80, (button, beside)     # next to it, not a card away
    page.click("#print-warning a")
    page.wait_for_timeout(300)
    assert page.url.endswith(f"#/job/{job}")                              # still the job's page
    top = page.locator("#j-shape").bounding_box()["y"]
    bar = page.locator("#bar").bounding_box()["height"]
    assert bar <= top < PHONE["height"] / 2, (bar, top)                   # the 3D view in view, below the bar
    shot(page, "36-print-warning-phone", full_page=False)
    assert not browser_page.errors, browser_page.errors
