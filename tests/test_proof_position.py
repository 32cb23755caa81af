"""``proof.expected_position``: the position a program line leaves the program at, from Marlin's
semantics of G90/G91/G92/G28 (a homed axis ends where the machine's endstops are: unknown), and
whether that position can prove the line ran (the position before it must differ)."""

from __future__ import annotations

import pytest

from ribbond.printer.proof import MIN_PROOF_MOVE_MM, POSITION_TOLERANCE_MM, at_position, expected_position

PROGRAM = [
    "G90",               # 0
    "G28",               # 1  every axis unknown
    "G1 Z0.3 F600",      # 2  Z known, nothing known before it
    "G1 X10 Y20",        # 3  X, Y become known; unknown before: cannot prove
    "G1 X12",            # 4  X 10 -> 12
    "M104 S200",         # 5  not a move
    "G91",               # 6
    "G1 X1 E0.5",        # 7  relative: X 12 -> 13
    "G1 X0.05",          # 8  moves less than MIN_PROOF_MOVE_MM
    "G90",               # 9
    "G01X20Y20",         # 10 no spaces, G01: X 13.05 -> 20
    "G92 X0",            # 11 not a move
    "G1 X5",             # 12 after G92 X0: X 0 -> 5
    "G28 X",             # 13
    "G1 X7 Y21",         # 14 X unknown before, Y 20 -> 21
    "G1 X7 Y21 E3",      # 15 same place: only E moves
]

CASES = [
    (0, None), (1, None), (2, None), (3, None),
    (4, {"X": 12.0, "Y": 20.0, "Z": 0.3}),
    (5, None), (6, None),
    (7, {"X": 13.0, "Y": 20.0, "Z": 0.3}),
    (8, None), (9, None),
    (10, {"X": 20.0, "Y": 20.0, "Z": 0.3}),
    (11, None),
    (12, {"X": 5.0, "Y": 20.0, "Z": 0.3}),
    (13, None),
    (14, {"X": 7.0, "Y": 21.0, "Z": 0.3}),
    (15, None),
]


@pytest.mark.parametrize(("index", "expected"), CASES)
def test_expected_position(index: int, expected: dict[str, float] | None) -> None:
    got = expected_position(PROGRAM, index)
    if expected is None:
        assert got is None
    else:
        assert got == pytest.approx(expected)


def test_a_line_outside_the_program_is_refused() -> None:
    with pytest.raises(ValueError, match="line index 3 outside the program's 2 lines"):
        expected_position(["G90", "G1 X1"], 3)


def test_at_position_within_the_report_resolution() -> None:
    expected = {"X": 12.0, "Y": 20.0}
    assert at_position((12.0 + POSITION_TOLERANCE_MM / 2, 20.0, 99.0), expected), "Z not known: not compared"
    assert not at_position((12.0 + 2 * POSITION_TOLERANCE_MM, 20.0, 0.0), expected)
    assert MIN_PROOF_MOVE_MM > 2 * POSITION_TOLERANCE_MM, "the position before a provable line never passes"


# The mutation run's survivors (issue 35): each command that makes the position unknown, G92 and G28
# by their axes, the program's first mode, and the bounds of MIN_PROOF_MOVE_MM and POSITION_TOLERANCE_MM.
KNOWN = "G1 X10 Y10 Z5"


@pytest.mark.parametrize("word", ["G29", "G30", "G33", "G34", "M48", "G53", "G54", "G55", "G56", "G57", "G58",
                                  "G59"])
def test_probing_and_coordinate_systems_make_every_axis_unknown(word: str) -> None:
    assert expected_position([KNOWN, word, "G91", "G1 X1"], 3) is None
    assert expected_position([KNOWN, word, "G1 X20"], 2) is None


def test_g92_sets_the_axes_it_names_and_without_axes_forgets_all() -> None:
    assert expected_position([KNOWN, "G92 X5", "G91", "G1 X1"], 3) == {"X": 6.0, "Y": 10.0, "Z": 5.0}
    assert expected_position([KNOWN, "G92", "G91", "G1 X1"], 3) is None


def test_g28_with_axes_forgets_those_alone() -> None:
    assert expected_position([KNOWN, "G28 X", "G91", "G1 Y1"], 3) == {"Y": 11.0, "Z": 5.0}


def test_a_relative_move_of_an_unknown_axis_stays_unknown() -> None:
    assert expected_position(["G91", "G1 X1"], 1) is None


def test_a_line_without_a_command_word_changes_nothing() -> None:
    assert expected_position(["", "; note", KNOWN, "X5", "G1 X20"], 4) == {"X": 20.0, "Y": 10.0, "Z": 5.0}


def test_a_program_starts_absolute() -> None:
    assert expected_position([KNOWN, "G1 X20"], 1) == {"X": 20.0, "Y": 10.0, "Z": 5.0}


def test_the_bounds_are_inclusive() -> None:
    assert expected_position(["G1 X0 Y0 Z5", f"G1 X{MIN_PROOF_MOVE_MM}"], 1) == {"X": MIN_PROOF_MOVE_MM, "Y": 0.0,
                                                                                 "Z": 5.0}
    assert at_position((POSITION_TOLERANCE_MM, 0.0, 0.0), {"X": 0.0, "Y": 0.0})


def test_the_line_just_past_the_end_is_refused() -> None:
    with pytest.raises(ValueError, match="line index 2 outside the program's 2 lines"):
        expected_position(["G90", "G1 X1"], 2)
