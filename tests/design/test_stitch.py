"""Stitch marks (issue 26): the font's glyphs stay in their cells, a tick runs from the seam line to the
cutting line, the label sits in the allowance and reads from outside the panel, bad input is named;
``design.json`` carries the marks (or, without them, is written as before); the preview draws them.

Expectations come from the geometry the docstrings state: the allowance is the band 0..L along the
outward normal, the label's up is -outward, and a reader outside the panel has the panel ahead."""

from __future__ import annotations

import io
import json
import string
import xml.etree.ElementTree as ET

import matplotlib.image as mpimg
import numpy as np
import pytest

from ribbond.design.format import FORMAT, StitchMark, design_from_json, design_to_json
from ribbond.panels.stitch import (ADVANCE, CELL_H, CELL_W, GLYPHS, TEXT_GAP, make_stitch_marks, seam_of,
                                   stitch_mark_strokes, strokes_length, text_strokes, text_width)

from .test_format import make_design
from .test_preview import SIGMA2_BOUNDS, rect_mesh, sigma2_of

CHARACTERS = string.ascii_uppercase + string.digits
SVG = "{http://www.w3.org/2000/svg}"

# marks on the four sides of a panel and on a slant: (at, outward)
ANGLES = np.radians([-90.0, 0.0, 90.0, 180.0, 33.0])
AT = np.array([[20.0, 10.0], [60.0, 30.0], [40.0, 70.0], [5.0, 40.0], [50.0, 50.0]])
OUTWARD = np.column_stack([np.cos(ANGLES), np.sin(ANGLES)])
LABELS = ["A1", "B12", "C3", "Z90", "Q7"]
L = 10.0


def frame_of(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(right, up) as a reader outside the panel sees the mark: the panel ahead (up = -n), right of it
    is -n turned a quarter clockwise."""
    up = -n
    return np.array([up[1], -up[0]]), up


# ----------------------------------------------------------------------------------------- glyphs


def test_every_letter_and_digit_has_strokes_inside_its_cell() -> None:
    assert set(GLYPHS) == set(CHARACTERS)
    for ch in CHARACTERS:
        strokes = GLYPHS[ch]
        assert strokes, ch
        for s in strokes:
            assert s.ndim == 2 and s.shape[1] == 2 and len(s) >= 2, ch
            assert (s >= 0).all() and (s[:, 0] <= CELL_W).all() and (s[:, 1] <= CELL_H).all(), ch
            assert np.linalg.norm(np.diff(s, axis=0), axis=1).min() > 0, f"{ch}: a stroke with a zero step"
        box = np.concatenate(strokes)
        assert np.ptp(box[:, 1]) == CELL_H, f"{ch}: a character spans the cap height"


def test_glyphs_are_distinct() -> None:
    shapes = {ch: sorted(tuple(map(tuple, s.round(6).tolist())) for s in GLYPHS[ch]) for ch in CHARACTERS}
    seen: dict[str, str] = {}
    for ch, shape in shapes.items():
        key = repr(shape)
        assert key not in seen, f"{ch} is drawn as {seen.get(key)}"
        seen[key] = ch


def test_text_is_scaled_and_advanced_cell_by_cell() -> None:
    h = 3.0
    strokes = text_strokes("IL", np.array([1.0, 2.0]), np.array([1.0, 0.0]), h)
    unit = h / CELL_H
    assert len(strokes) == len(GLYPHS["I"]) + len(GLYPHS["L"])
    i_pts = np.concatenate(strokes[:3])
    assert np.allclose(i_pts.min(axis=0), [1.0 + 1 * unit, 2.0]) and np.allclose(i_pts.max(axis=0), [1.0 + 3 * unit, 2.0 + h])
    assert np.allclose(strokes[3], [[1.0 + ADVANCE * unit, 2.0 + h], [1.0 + ADVANCE * unit, 2.0],
                                    [1.0 + (ADVANCE + CELL_W) * unit, 2.0]])
    assert text_width("IL", h) == pytest.approx((ADVANCE + CELL_W) * unit)
    # I is 2 + 6 + 2 units of stroke, L 6 + 4
    assert strokes_length(strokes) == pytest.approx(20 * unit)


# ----------------------------------------------------------------------------------------- marks


@pytest.fixture(scope="module")
def marks() -> list[list[np.ndarray]]:
    return stitch_mark_strokes(AT, OUTWARD, LABELS, L)


def test_the_tick_runs_from_the_seam_line_to_the_cutting_line(marks) -> None:  # type: ignore[no-untyped-def]
    for i, strokes in enumerate(marks):
        tick = strokes[0]
        assert tick.shape == (2, 2)
        assert np.allclose(tick[0], AT[i]) and np.allclose(tick[1], AT[i] + L * OUTWARD[i])
        assert len(strokes) == 1 + sum(len(GLYPHS[ch]) for ch in LABELS[i])


def test_the_label_sits_in_the_allowance_beside_the_tick(marks) -> None:  # type: ignore[no-untyped-def]
    h = 0.4 * L
    for i, strokes in enumerate(marks):
        label = np.concatenate(strokes[1:]) - AT[i]
        right, up = frame_of(OUTWARD[i])
        out = label @ OUTWARD[i]
        across = label @ right
        assert out.min() > 0 and out.max() < L, f"{LABELS[i]}: outside the allowance band 0..{L}"
        assert out.max() - out.min() == pytest.approx(h), f"{LABELS[i]}: the text is {h} mm high"
        assert across.min() >= TEXT_GAP * h - 1e-9, f"{LABELS[i]}: the label starts beside the tick, to its right"
        assert across.max() <= TEXT_GAP * h + text_width(LABELS[i], h) + 1e-9


def test_the_label_reads_from_outside_the_panel() -> None:
    """An "L" seen from outside: its stem on the left, its foot on the baseline, the farthest out."""
    for n in OUTWARD:
        stroke = stitch_mark_strokes(np.zeros((1, 2)), n[None], ["L"], L)[0][1]   # top, corner, foot end
        right, up = frame_of(n)
        top, corner, foot = stroke
        assert (top - corner) @ up == pytest.approx(0.4 * L)            # the stem rises towards the panel
        assert (foot - corner) @ right > 0                              # the foot goes to the reader's right
        assert corner @ n == pytest.approx(0.7 * L)                     # the baseline: outer edge of the band


def test_text_height_can_be_given() -> None:
    strokes = stitch_mark_strokes(AT[:1], OUTWARD[:1], ["H"], 8.0, text_height=2.0)[0]
    out = (np.concatenate(strokes[1:]) - AT[0]) @ OUTWARD[0]
    assert out.min() == pytest.approx(3.0) and out.max() == pytest.approx(5.0)


@pytest.mark.parametrize("change, message", [
    (dict(at=np.zeros(2)), r"at must have shape \(p, 2\)"),
    (dict(outward=OUTWARD[:2]), "outward must have the shape of at"),
    (dict(outward=OUTWARD * [[1.0], [1.0], [1.01], [1.0], [1.0]]), r"outward\[2\] .* must be a unit vector"),
    (dict(at=AT + [[0.0, 0.0], [np.nan, 0.0], [0, 0], [0, 0], [0, 0]]), r"at\[1\] .* is not finite"),
    (dict(labels=LABELS[:4]), "labels must be a list of 5 strings"),
    (dict(labels=["A1", "B12", "c3", "Z90", "Q7"]), r"labels\[2\] = 'c3': character 'c' has no glyph"),
    (dict(labels=["A1", "B-2", "C3", "Z90", "Q7"]), r"labels\[1\] = 'B-2': character '-' has no glyph"),
    (dict(labels=["A1", "", "C3", "Z90", "Q7"]), r"labels\[1\] = '': a label is a non-empty string"),
    (dict(tick_length=0.0), "tick_length = 0.0: must be a finite number > 0"),
    (dict(text_height=10.0), "text_height = 10.0: must be > 0 and below tick_length"),
])
def test_bad_input_is_named(change: dict[str, object], message: str) -> None:
    args: dict[str, object] = dict(at=AT, outward=OUTWARD, labels=LABELS, tick_length=L)
    args.update(change)
    with pytest.raises(ValueError, match=message):
        stitch_mark_strokes(**args)  # type: ignore[arg-type]


def test_the_seam_is_the_labels_leading_letters() -> None:
    assert [seam_of(x) for x in ("A1", "B12", "AA3")] == ["A", "B", "AA"]
    with pytest.raises(ValueError, match="'12' starts with no seam letter"):
        seam_of("12")


# ----------------------------------------------------------------------------------------- design.json


def test_design_json_without_stitch_marks_is_written_as_before() -> None:
    design = make_design(4)
    text = design_to_json(design)
    assert "stitch_marks" not in json.loads(text) and design.stitch_marks is None
    assert design_from_json(text) == design and json.loads(text)["format"] == FORMAT


def test_design_json_round_trips_the_stitch_marks() -> None:
    stitches = make_stitch_marks(AT, OUTWARD, LABELS, L)
    design = make_design(4).updated(stitch_marks=stitches)
    text = design_to_json(design)
    data = json.loads(text)
    assert list(data).index("stitch_marks") == list(data).index("registration_marks") + 1
    assert data["stitch_marks"][1]["label"] == "B12" and data["stitch_marks"][1]["seam"] == "B"
    again = design_from_json(text)
    assert again == design and design_to_json(again) == text
    for mark, strokes in zip(again.stitch_marks or [], stitch_mark_strokes(AT, OUTWARD, LABELS, L)):
        assert all(np.array_equal(a, b) for a, b in zip(mark.arrays(), strokes))


@pytest.mark.parametrize("field, value, message", [
    ("outward", [0.0, 2.0], r"stitch_marks\[0\]\.outward: .* must be a unit vector"),
    ("label", "a1", r"stitch_marks\[0\]\.label"),
    ("strokes", [[[0.0, 0.0]]], r"stitch_marks\[0\]\.strokes: .*strokes\[0\] has 1 point"),
])
def test_a_bad_stitch_mark_in_design_json_is_named(field: str, value: object, message: str) -> None:
    data = json.loads(design_to_json(make_design(4).updated(stitch_marks=make_stitch_marks(AT, OUTWARD, LABELS, L))))
    data["stitch_marks"][0][field] = value
    with pytest.raises(ValueError, match=message):
        design_from_json(json.dumps(data))


# ----------------------------------------------------------------------------------------- preview


def test_the_preview_draws_every_stroke_as_a_thin_dark_line() -> None:
    from ribbond.design.preview import render_preview
    uv, F = rect_mesh()                                          # the panel [0, 100]²
    s2 = sigma2_of(uv, F)
    at, n = np.array([[30.0, 20.0], [20.0, 60.0]]), np.array([[0.0, 1.0], [1.0, 0.0]])
    stitches = make_stitch_marks(at, n, ["A1", "B2"], L)
    svg, png = render_preview(uv, F, s2, [], 4.0, sigma2_bounds=SIGMA2_BOUNDS, dpi=60, stitch_marks=stitches)
    group = [g for g in ET.fromstring(svg).iter(f"{SVG}g") if g.get("id") == "stitch-marks"]
    assert len(group) == 1
    assert len(list(group[0].iter(f"{SVG}path"))) == sum(len(m.strokes) for m in stitches)
    # the same strokes as polylines, 50 mm to the right (the same view and legend): each picture is
    # darker than the other where its own marks are
    moved = [[s + [50.0, 0.0] for s in m.arrays()] for m in stitches]
    _, png_moved = render_preview(uv, F, s2, [], 4.0, sigma2_bounds=SIGMA2_BOUNDS, dpi=60, stitch_marks=moved)
    a, b = (mpimg.imread(io.BytesIO(x))[..., :3].sum(axis=-1) for x in (png, png_moved))
    assert a.shape == b.shape
    here, there = np.argwhere(b - a > 0.6), np.argwhere(a - b > 0.6)    # (row, column) of darker pixels
    assert len(here) > 100 and len(there) > 100
    assert there[:, 1].mean() - here[:, 1].mean() > 0.3 * a.shape[1] * 50 / 130
    with pytest.raises(ValueError, match=r"stitch_marks\[0\] stroke 1 has 1 point"):
        render_preview(uv, F, s2, [], 4.0, stitch_marks=[[np.zeros((2, 2)), np.zeros((1, 2))]])


def test_a_stitch_mark_model_is_what_the_preview_takes() -> None:
    from ribbond.design.preview import StitchMarkLike
    assert isinstance(make_stitch_marks(AT[:1], OUTWARD[:1], ["A1"], L)[0], StitchMarkLike)
    assert StitchMark.model_fields["strokes"].is_required()
