"""The generator's safety limits, each guarded by a test that fails when the check is lost (issue 22,
item 11): every move of every program within each axis' maximum speed, Z-only moves at the
profile's Z speed, the writer refusing a move above any axis' maximum, and every registration mark
printed (both strokes of its cross, each reaching across the mark) in the front and the combined
program. Read by the independent reader; expectations from the profile and the design's marks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ribbond.gcode.program import GcodeError, _check_limits, _Writer

from .conftest import PROGRAMS, SaddleDesign, pause_line, type_labels


def _limits(profile) -> dict[str, float]:  # type: ignore[no-untyped-def]
    m = profile.motion
    return {"X": m.max_xy_speed, "Y": m.max_xy_speed, "Z": m.max_z_speed, "E": m.max_e_speed}


@pytest.mark.parametrize("name", PROGRAMS)
def test_every_move_keeps_each_axis_within_its_maximum_speed(saddle_design: SaddleDesign, name: str) -> None:
    limits = _limits(saddle_design.profile)
    over = [f"line {m.line}: {axis} at {speed:.2f} mm/s > {limits[axis]:g}"
            for m in saddle_design.read[name].moves for axis, speed in m.axis_speeds().items()
            if not math.isnan(speed) and speed > limits[axis] + 1e-9]
    assert not over, over[:10]


@pytest.mark.parametrize("name", PROGRAMS)
def test_z_only_moves_go_at_the_profiles_z_speed(saddle_design: SaddleDesign, name: str) -> None:
    """Lifts, hops and descents onto the fabric: Z alone, at ``z_speed`` (not the travel speed)."""
    z_speed = saddle_design.profile.motion.z_speed
    z_moves = [m for m in saddle_design.read[name].moves if m.kind == "z"]
    assert len(z_moves) > 10, "the program should lift and lower the nozzle between parts"
    wrong = [(m.line, m.feed) for m in z_moves if m.feed != pytest.approx(z_speed * 60)]
    assert not wrong, f"Z-only moves not at z_speed {z_speed:g} mm/s (F{z_speed * 60:g}): {wrong[:10]}"


@pytest.mark.parametrize("axis", ["X", "Y", "Z", "E"])
def test_the_writer_refuses_a_move_above_an_axis_maximum(saddle_design: SaddleDesign, axis: str) -> None:
    prof = saddle_design.profile
    limit = _limits(prof)[axis]
    w = _Writer(prof, None)
    cx, cy = prof.frame.center
    w.pos = np.array([cx, cy, 5.0])
    if axis == "E":
        w.moves.append((cx, cy, 5.0, cx, cy, 5.0, -1.0, limit + 1, False))
    else:
        end = np.array([cx, cy, 5.0]) + np.eye(3)["XYZ".index(axis)]
        w._move("G0", end, 0.0, limit + 1, False)
    with pytest.raises(GcodeError, match=f"maximum of {limit:g} mm/s"):
        _check_limits(w, "test.gcode")
    w = _Writer(prof, None)                                  # at the limit: accepted
    w.pos = np.array([cx, cy, 5.0])
    w._move("G0", np.array([cx, cy, 6.0]), 0.0, prof.motion.max_z_speed, False)
    _check_limits(w, "test.gcode")


@pytest.mark.parametrize("name", ["front", "combined"])
def test_every_registration_mark_is_printed_as_a_whole_cross(saddle_design: SaddleDesign, name: str) -> None:
    """Each mark of the design: two extruded strokes through it, one along x and one along y, each
    reaching across it (its ends on both sides of the mark); on the front, before the flip."""
    program = saddle_design.read[name]
    marks = np.asarray(saddle_design.design.registration_marks, dtype=float)
    nozzle = saddle_design.profile.extruder.nozzle_diameter
    assert len(marks) >= 3, "the design should have registration marks to align the back with"
    end = pause_line(program) if name == "combined" else math.inf
    strokes: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for move, label in zip(program.moves, type_labels(program)):
        if label is not None and label[0] == "REGISTRATION" and move.kind == "extrude":
            assert move.line < end, f"line {move.line}: a registration mark printed after the flip"
            strokes.setdefault(label[1], []).append((np.asarray(move.start[:2]), np.asarray(move.end[:2])))
    assert sorted(strokes) == list(range(len(marks))), f"marks printed: {sorted(strokes)} of {len(marks)}"
    for index, mark in enumerate(marks):
        for along in (0, 1):                                 # the stroke along x, the stroke along y
            across = 1 - along
            found = [(a, b) for a, b in strokes[index]
                     if abs(a[across] - mark[across]) < 1e-3 and abs(b[across] - mark[across]) < 1e-3
                     and min(a[along], b[along]) < mark[along] - nozzle
                     and max(a[along], b[along]) > mark[along] + nozzle]
            assert found, f"mark {index} at {mark}: no stroke along {'xy'[along]} across it: {strokes[index]}"
