"""A panel's stitch marks in the programs (issue 26): the front program deposits every stroke, one layer
a nozzle wide, the back program none; the combined program prints them before the flip; a stroke
outside the frame is refused; the figures count them; the checker finds every stroke printed.

A small hand-made design (one front and one back ribbon, three registration marks, four stitch marks
on the sides of a 60 mm square panel) keeps it fast; the programs are read by tests/gcode/reader.py
and the coverage measured with shapely."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from ribbond.design.format import Ribbon
from ribbond.panels.stitch import make_stitch_marks, strokes_length
from ribbond.gcode.checker import check_stitch_marks
from ribbond.gcode.profiles import load_profile
from ribbond.gcode.program import GcodeError, make_programs

from ..design.test_format import make_design
from .conftest import PROFILE, mirror_to_back, pause_line, type_labels
from .reader import read_gcode

PANEL = (80.0, 80.0, 140.0, 140.0)          # x0, y0, x1, y1 of the panel's seam lines, mm
AT = np.array([[110.0, 80.0], [140.0, 110.0], [110.0, 140.0], [80.0, 110.0]])
OUTWARD = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
LABELS = ["A1", "B1", "C12", "D3"]
ALLOWANCE = 10.0


def design_with(stitches):  # type: ignore[no-untyped-def]
    ribbons = [Ribbon(side="front", points=[(90.0, 100.0), (130.0, 102.0)], thickness=0.6, kappa1=0.031,
                      spacing=(22.9, 6.1)),
               Ribbon(side="back", points=[(90.0, 120.0), (110.0, 121.0), (130.0, 120.0)], thickness=0.4,
                      kappa1=-0.02, spacing=(21.0, 5.0))]
    return make_design(4).updated(ribbons=ribbons, registration_marks=[(70.0, 70.0), (150.0, 70.0), (70.0, 150.0)],
                                  stitch_marks=stitches)


@pytest.fixture(scope="module")
def made():  # type: ignore[no-untyped-def]
    stitches = make_stitch_marks(AT, OUTWARD, LABELS, ALLOWANCE)
    profile = load_profile(PROFILE)
    with_marks = make_programs(design_with(stitches), profile, move_budget=0)
    without = make_programs(design_with(None), profile, move_budget=0)
    return stitches, profile, with_marks, without


def deposits(program, lo: int = 0, hi: int | None = None):  # type: ignore[no-untyped-def]
    """(segments (k, 2, 2), z (k,)) of the extruding moves of ``program.moves[lo:hi]``."""
    moves = [m for m in program.moves[lo:hi] if m.extruding]
    return (np.array([(m.start[:2], m.end[:2]) for m in moves]).reshape(-1, 2, 2),
            np.array([m.end[2] for m in moves]))


def test_the_front_deposits_every_stroke_on_the_first_layer(made) -> None:  # type: ignore[no-untyped-def]
    stitches, profile, programs, _ = made
    front = read_gcode(programs.front.text)
    segments, z = deposits(front)
    half = 0.5 * profile.extruder.nozzle_diameter
    first = np.isclose(z, profile.layers.fabric_z + profile.layers.first_layer_height, atol=1e-6)
    printed = shapely.buffer(shapely.MultiLineString(list(segments[first])), half + 1e-3)
    for mark in stitches:
        for k, stroke in enumerate(mark.arrays()):
            assert printed.contains(shapely.LineString(stroke)), f"{mark.label} stroke {k} is not printed"
    kinds = [lab for lab in type_labels(front) if lab is not None and lab[0] == "STITCH"]
    assert sorted(set(kinds)) == [("STITCH", i) for i in range(len(stitches))]


def test_the_back_prints_none_and_the_combined_prints_them_before_the_flip(made) -> None:  # type: ignore[no-untyped-def]
    stitches, profile, programs, _ = made
    back = read_gcode(programs.back.text)
    assert "TYPE:STITCH" not in programs.back.text
    segments, _ = deposits(back)
    # no plastic on the back where the marks are (in back-side coordinates, mirrored)
    lines = shapely.MultiLineString(list(segments))
    for mark in stitches:
        for stroke in mark.arrays():
            assert shapely.distance(lines, shapely.LineString(mirror_to_back(stroke, profile))) > 1.0
    combined = read_gcode(programs.combined.text)
    flip = pause_line(combined)
    lines_of = [line for line, text in combined.comments if text.startswith("TYPE:STITCH")]
    assert len(lines_of) == len(stitches) and max(lines_of) < flip


def test_the_figures_count_the_strokes(made) -> None:  # type: ignore[no-untyped-def]
    stitches, _, programs, without = made
    length = sum(strokes_length(m.arrays()) for m in stitches)
    added = programs.front.stats.extrusion_mm - without.front.stats.extrusion_mm
    assert added == pytest.approx(length, rel=1e-6)
    assert programs.front.stats.time_s > without.front.stats.time_s + length / 15.0   # at most 15 mm/s
    assert programs.back.stats == without.back.stats


def test_the_checker_finds_every_stroke_printed(made) -> None:  # type: ignore[no-untyped-def]
    stitches, profile, programs, without = made
    check_stitch_marks(programs.front.text.splitlines(), stitches, profile)
    with pytest.raises(ValueError, match="front.gcode does not print stroke 0 of stitch mark A1 \\(the tick\\)"):
        check_stitch_marks(without.front.text.splitlines(), stitches, profile)
    # a label stroke left out: the part of mark C12 cut from the program
    lines = programs.front.text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(";TYPE:STITCH 2"))
    end = next(i for i in range(start, len(lines)) if lines[i].startswith("M400"))
    cut = lines[:start] + [line for line in lines[start:end] if not line.startswith("G1 X")] + lines[end:]
    with pytest.raises(ValueError, match="stitch mark C12"):
        check_stitch_marks(cut, stitches, profile)


def test_a_stroke_outside_the_frame_is_refused(made) -> None:  # type: ignore[no-untyped-def]
    _, profile, _, _ = made
    x0 = profile.frame.bounds[0]
    outside = make_stitch_marks(np.array([[x0 + 5.0, 110.0]]), np.array([[-1.0, 0.0]]), ["E1"], ALLOWANCE)
    with pytest.raises(GcodeError, match=r"front.gcode: .* outside the frame rectangle .* stitch mark 0"):
        make_programs(design_with(outside), profile, move_budget=0)
