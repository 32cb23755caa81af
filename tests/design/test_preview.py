"""The layout preview: PNG and SVG bytes, ribbons at their real width, deterministic, checked inputs."""

from __future__ import annotations

import io
import re
import threading
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import matplotlib.image as mpimg
import numpy as np
import pytest
from scipy import ndimage

from ribbond.design.format import Ribbon
from ribbond.design.preview import RibbonLike, _light_colormap, boundary_edges, render_preview

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SVG = "{http://www.w3.org/2000/svg}"
SIGMA2_BOUNDS = (1.3, 1.5)


@dataclass(frozen=True)
class R:
    side: str
    points: list[tuple[float, float]]


def rect_mesh(w: float = 100.0, h: float = 100.0, nx: int = 20, ny: int = 20
              ) -> tuple[np.ndarray, np.ndarray]:
    """The rectangle [0, w] × [0, h] as a grid: (nx+1)(ny+1) vertices, 2 nx ny CCW faces."""
    x, y = np.meshgrid(np.linspace(0.0, w, nx + 1), np.linspace(0.0, h, ny + 1))
    uv = np.column_stack([x.ravel(), y.ravel()])
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return uv, F


def sigma2_of(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """σ2 rising from 1.3 at x = 0 to 1.5 at x = 100 (by face centroid)."""
    return 1.3 + 0.2 * uv[F].mean(axis=1)[:, 0] / 100.0


# A horizontal front ribbon 60 mm long at y = 50, two short back ones, a bent front one.
RIBBONS = [R("front", [(20.0, 50.0), (50.0, 50.0), (80.0, 50.0)]),
           R("back", [(20.0, 80.0), (40.0, 80.0)]),
           R("back", [(60.0, 80.0), (75.0, 85.0)]),
           R("front", [(20.0, 20.0), (30.0, 22.0), (40.0, 26.0)])]
MARKS = np.array([[-5.0, -5.0], [105.0, -5.0], [-5.0, 105.0]])


def render(ribbons=RIBBONS, width: float = 4.0, **kw: object) -> tuple[bytes, bytes]:
    uv, F = rect_mesh()
    kw.setdefault("sigma2_bounds", SIGMA2_BOUNDS)
    kw.setdefault("dpi", 100)
    return render_preview(uv, F, sigma2_of(uv, F), ribbons, width, **kw)  # type: ignore[arg-type]


def image(png: bytes) -> np.ndarray:
    img = mpimg.imread(io.BytesIO(png))
    return img[..., :3]


def red(img: np.ndarray) -> np.ndarray:
    return (img[..., 0] > 0.7) & (img[..., 1] < 0.3) & (img[..., 2] < 0.3)


def blue(img: np.ndarray) -> np.ndarray:
    return (img[..., 2] > 0.7) & (img[..., 0] < 0.3) & (img[..., 1] < 0.45)


def components(mask: np.ndarray) -> list[tuple[int, slice, slice]]:
    """(pixel count, rows, columns) of each connected region of ``mask``, largest first."""
    labels, n = ndimage.label(mask)
    sizes = ndimage.sum_labels(mask, labels, index=np.arange(1, n + 1)).astype(int)
    boxes = ndimage.find_objects(labels)
    return sorted(((s, *b) for s, b in zip(sizes, boxes)), key=lambda t: -t[0])


@pytest.fixture(scope="module")
def full() -> tuple[bytes, bytes]:
    return render(marks=MARKS, frame_bounds=(-10.0, -10.0, 110.0, 110.0), title="test layout")


def test_png_decodes_to_a_square_ish_image(full: tuple[bytes, bytes]) -> None:
    svg, png = full
    assert svg and png
    assert png.startswith(PNG_SIGNATURE)
    img = image(png)
    h, w = img.shape[:2]
    assert 500 < w < 2000 and 500 < h < 2000
    assert 0.7 < h / w < 1.3  # a square layout (the colour bar widens it, title and legend heighten it)


def test_wide_layout_gives_a_wide_image_even_with_constant_sigma2_and_nothing_else() -> None:
    uv, F = rect_mesh(200.0, 40.0, 20, 4)
    svg, png = render_preview(uv, F, np.full(len(F), 1.4), [], 1.5, marks=[], dpi=40)
    h, w = image(png).shape[:2]
    assert w > 1.6 * h
    ET.fromstring(svg)


def test_svg_is_well_formed_with_vector_layers_and_a_raster_colour_map(full: tuple[bytes, bytes]) -> None:
    svg, _ = full
    root = ET.fromstring(svg)
    assert root.tag == f"{SVG}svg"
    ids = {el.get("id"): el for el in root.iter() if el.get("id")}
    for gid in ("front-ribbons", "back-ribbons", "outline", "frame", "registration-marks-circles",
                "registration-marks-crosses"):
        assert gid in ids, gid
        assert list(ids[gid].iter(f"{SVG}path")) + list(ids[gid].iter(f"{SVG}use")), gid
    for side in ("front", "back"):
        paths = list(ids[f"{side}-ribbons"].iter(f"{SVG}path"))
        assert paths and all(p.get("d") for p in paths)
    # σ2 is an embedded raster image (with the colour bar's), not 800 polygons
    assert list(root.iter(f"{SVG}image"))
    uv, F = rect_mesh()
    assert len(list(root.iter(f"{SVG}path"))) < len(F) / 2


def test_marks_are_numbered_from_1_and_the_flip_axis_is_drawn(full: tuple[bytes, bytes]) -> None:
    """Each registration mark carries its number (1..k, as the daemon's alignment counts them), and
    the flip axis goes through the frame's centre (a vertical line for the default axis "y")."""
    root = ET.fromstring(full[0])
    ids = {el.get("id"): el for el in root.iter() if el.get("id")}
    numbered = sorted(int(i.rsplit("-", 1)[1]) for i in ids if re.fullmatch(r"registration-mark-\d+", i))
    assert numbered == list(range(1, len(MARKS) + 1))
    assert "flip-axis" in ids
    [path] = list(ids["flip-axis"].iter(f"{SVG}path"))
    xs, ys = zip(*((float(a), float(b)) for a, b in re.findall(r"(-?[\d.]+)[ ,](-?[\d.]+)", path.get("d"))))
    assert max(xs) - min(xs) < 1e-6 < max(ys) - min(ys)                  # vertical: x = centre
    svg, _ = render(marks=MARKS, frame_bounds=(-10.0, -10.0, 110.0, 110.0), flip_axis="x")
    [path] = list({el.get("id"): el for el in ET.fromstring(svg).iter() if el.get("id")}["flip-axis"].iter(f"{SVG}path"))
    xs, ys = zip(*((float(a), float(b)) for a, b in re.findall(r"(-?[\d.]+)[ ,](-?[\d.]+)", path.get("d"))))
    assert max(ys) - min(ys) < 1e-6 < max(xs) - min(xs)                  # horizontal
    svg, _ = render(marks=MARKS, frame_bounds=(-10.0, -10.0, 110.0, 110.0), flip_axis=None)
    assert b'id="flip-axis"' not in svg
    with pytest.raises(ValueError, match="flip_axis"):
        render(marks=MARKS, frame_bounds=(-10.0, -10.0, 110.0, 110.0), flip_axis="z")


def test_svg_is_deterministic(full: tuple[bytes, bytes]) -> None:
    svg, png = render(marks=MARKS, frame_bounds=(-10.0, -10.0, 110.0, 110.0), title="test layout")
    assert svg == full[0]
    assert png == full[1]
    assert b"<dc:date>" not in svg


def test_renders_in_threads_agree() -> None:
    out: list[bytes] = []

    def run() -> None:
        out.append(render(title="cost $5 $x$.obj", dpi=30)[0])  # "$" is no mathtext in the title

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(out) == 2 and out[0] == out[1]


def test_ribbons_in_their_colours_at_their_real_width(full: tuple[bytes, bytes]) -> None:
    img = image(full[1])
    reds, blues = components(red(img)), components(blue(img))
    assert reds and blues
    # the largest red region is the straight 60 mm × 4 mm ribbon; its pixel size gives the scale
    _, rows, cols = reds[0]
    length_px, width_px = cols.stop - cols.start, rows.stop - rows.start
    px_per_mm = length_px / 60.0
    assert px_per_mm > 5
    assert width_px / px_per_mm == pytest.approx(4.0, abs=2.5 / px_per_mm)
    # the back ribbons are blue: the 20 mm horizontal one is among the largest blue regions
    assert blues[0][0] > 0.5 * 20.0 * 4.0 * px_per_mm ** 2

    # σ2 underneath: sample the map left and right of the ribbon, mapping mm to pixels from it
    x0_px = cols.start - 20.0 * px_per_mm
    y50_px = 0.5 * (rows.start + rows.stop)
    cmap = _light_colormap()
    for x_mm in (7.5, 92.5):
        px = img[int(round(y50_px + 15.0 * px_per_mm)), int(round(x0_px + x_mm * px_per_mm))]
        sigma = 1.3 + 0.2 * x_mm / 100.0
        expected = np.asarray(cmap((sigma - 1.3) / 0.2))[:3]
        assert np.abs(px - expected).max() < 0.08, (x_mm, px, expected)


def test_same_width_at_another_figure_size() -> None:
    # the frame makes the layout larger, so the mesh is smaller in pixels: the ribbon's
    # width keeps its ratio to its length
    _, png = render(frame_bounds=(-100.0, -60.0, 250.0, 160.0), dpi=80, ribbons=RIBBONS[:1], width=6.0)
    _, rows, cols = components(red(image(png)))[0]
    px_per_mm = (cols.stop - cols.start) / 60.0
    assert (rows.stop - rows.start) / px_per_mm == pytest.approx(6.0, abs=2.5 / px_per_mm)


def test_no_blue_without_back_ribbons_and_the_model_ribbon_works() -> None:
    ribbons = [Ribbon(side="front", points=[(10.0, 10.0), (90.0, 90.0)], thickness=0.6, kappa1=0.02,
                      spacing=(20.0, 6.0))]
    assert isinstance(ribbons[0], RibbonLike)
    _, png = render(ribbons=ribbons, width=3.0, dpi=60)
    img = image(png)
    # the legend's swatch is the only blue: small, while the ribbon is a large red region
    assert components(red(img))[0][0] > 2000
    assert all(size < 400 for size, _, _ in components(blue(img)))


def test_boundary_edges_of_a_grid_and_of_two_pieces() -> None:
    uv, F = rect_mesh(10.0, 10.0, 4, 3)
    b = boundary_edges(F)
    assert len(b) == 2 * (4 + 3)
    assert np.all(np.bincount(b.ravel(), minlength=len(uv))[np.unique(b)] == 2)  # closed loop
    # two disjoint pieces: two loops, every edge oriented as in its face (CCW: interior on the left)
    F2 = np.vstack([F, F + len(uv)])
    b2 = boundary_edges(F2)
    assert len(b2) == 2 * len(b)
    uv2 = np.vstack([uv, uv + 20.0])
    d = uv2[b2[:, 1]] - uv2[b2[:, 0]]
    mid = 0.5 * (uv2[b2[:, 1]] + uv2[b2[:, 0]])
    centre = np.where((mid[:, :1] < 15.0), [5.0, 5.0], [25.0, 25.0])
    assert np.all(d[:, 0] * (centre - mid)[:, 1] - d[:, 1] * (centre - mid)[:, 0] > 0)


@pytest.mark.parametrize("change, message", [
    (dict(flat_uv=np.zeros((5, 3))), "flat_uv must have shape"),
    (dict(flat_uv="nan"), "flat_uv"),
    (dict(F=np.zeros((4, 4), dtype=int)), "F must have shape"),
    (dict(F=np.zeros((4, 3))), "integer"),
    (dict(F=np.array([[0, 1, 999]])), "F[0]"),
    (dict(sigma2=np.ones(3)), "sigma2 has 3 values"),
    (dict(sigma2="with_nan"), "sigma2[5]"),
    (dict(ribbon_width=0.0), "ribbon_width"),
    (dict(ribbons=[R("front", [(0, 0), (1, 1)]), R("front", [(0, 0), (1, 1)]), R("back", [(1.0, 1.0)])]),
     "ribbons[2] has 1 point"),
    (dict(ribbons=[R("front", [(0, 0), (1, 1)]), R("top", [(0, 0), (1, 1)])]), "ribbons[1] has side 'top'"),
    (dict(ribbons=[R("front", [(0, 0), (np.inf, 1)])]), "ribbons[0].points"),
    (dict(marks=np.zeros((3, 3))), "marks must have shape"),
    (dict(marks=np.array([[0.0, np.nan]])), "marks[0]"),
    (dict(frame_bounds=(10.0, 0.0, 0.0, 10.0)), "frame_bounds"),
    (dict(sigma2_bounds=(1.5, 1.3)), "sigma2_bounds"),
    (dict(dpi=0), "dpi"),
])
def test_bad_input_is_named(change: dict[str, object], message: str) -> None:
    uv, F = rect_mesh(10.0, 10.0, 2, 2)
    args: dict[str, object] = dict(flat_uv=uv, F=F, sigma2=np.full(len(F), 1.4), ribbons=[],
                                   ribbon_width=1.5)
    args.update(change)
    if isinstance(args["flat_uv"], str):
        args["flat_uv"] = np.where(np.arange(len(uv))[:, None] == 4, np.nan, uv)
    if isinstance(args["sigma2"], str):
        args["sigma2"] = np.where(np.arange(len(F)) == 5, np.nan, 1.4)
    with pytest.raises(ValueError) as err:
        render_preview(**args)  # type: ignore[arg-type]
    assert message in str(err.value)
