"""The test-only G-code reader, on small hand-written programs with values worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from .reader import Move, read_gcode

NAN = math.nan


def lines(*rows: str) -> str:
    return "\n".join(rows) + "\n"


def summary(move: Move) -> tuple:
    return (move.line, move.start, move.end, move.e, move.feed, move.command, move.kind)


def assert_moves(text: str, expected: list[tuple]) -> None:
    got = [summary(m) for m in read_gcode(text).moves]
    assert [g[0] for g in got] == [e[0] for e in expected], "move lines"
    for g, e in zip(got, expected, strict=True):
        line = g[0]
        np.testing.assert_allclose(g[1], e[1], atol=1e-12, err_msg=f"start, line {line}")  # NaN == NaN here
        np.testing.assert_allclose(g[2], e[2], atol=1e-12, err_msg=f"end, line {line}")
        np.testing.assert_allclose(g[3:5], e[3:5], atol=1e-12, err_msg=f"e and feed, line {line}")
        assert g[5:] == e[5:], f"command and kind, line {line}"


# (id, program, [(line, start, end, e, feed, command, kind), ...])
MOVE_CASES = [
    (
        "absolute E",
        lines(
            "G28",
            "G90",
            "M82",
            "G92 E0",
            "G1 X10 Y0 E1 F1200",
            "G1 X10 Y5 E1.5",
            "G1 E0.5 ; retract",
            "G1 E1.5 ; unretract",
            "G0 X0 Y0 F6000",
            "G1 Z0.3",
        ),
        [
            (5, (0, 0, 0), (10, 0, 0), 1.0, 1200, "G1", "extrude"),
            (6, (10, 0, 0), (10, 5, 0), 0.5, 1200, "G1", "extrude"),
            (7, (10, 5, 0), (10, 5, 0), -1.0, 1200, "G1", "retract"),
            (8, (10, 5, 0), (10, 5, 0), 1.0, 1200, "G1", "unretract"),
            (9, (10, 5, 0), (0, 0, 0), 0.0, 6000, "G0", "travel"),
            (10, (0, 0, 0), (0, 0, 0.3), 0.0, 6000, "G1", "z"),
        ],
    ),
    (
        "relative E (M83), no G92 needed",
        lines(
            "G28",
            "M83",
            "G1 X5 E0.5 F900",
            "G1 X5 Y5 E0.5",
            "G1 E-0.8",
            "G1 E0.8",
            "G1 X0 Y0 E-0.2",  # a wipe: retraction while moving is still a travel
        ),
        [
            (3, (0, 0, 0), (5, 0, 0), 0.5, 900, "G1", "extrude"),
            (4, (5, 0, 0), (5, 5, 0), 0.5, 900, "G1", "extrude"),
            (5, (5, 5, 0), (5, 5, 0), -0.8, 900, "G1", "retract"),
            (6, (5, 5, 0), (5, 5, 0), 0.8, 900, "G1", "unretract"),
            (7, (5, 5, 0), (0, 0, 0), -0.2, 900, "G1", "travel"),
        ],
    ),
    (
        "G91 moves XYZ and E relative, G90 back to absolute",
        lines(
            "G28",
            "G92 E0",
            "G91",
            "G1 X1 Y2 E0.1 F600",
            "G1 X1 Y2 Z0.5 E0.1",
            "G90",
            "G1 X0 Y0 E0.5",  # absolute E again: 0.5 - 0.2
        ),
        [
            (4, (0, 0, 0), (1, 2, 0), 0.1, 600, "G1", "extrude"),
            (5, (1, 2, 0), (2, 4, 0.5), 0.1, 600, "G1", "extrude"),
            (7, (2, 4, 0.5), (0, 0, 0.5), 0.3, 600, "G1", "extrude"),
        ],
    ),
    (
        "G90/G91 reset E's mode, M82/M83 then override E alone",
        lines(
            "G28",
            "G92 E0",
            "M83",
            "G90",  # Marlin: E absolute again
            "G1 X1 E2 F1000",  # e = 2 - 0
            "G1 X2 E3",  # e = 3 - 2
            "M83",
            "G1 X3 E3",  # relative: e = 3, E position 6
            "G91",
            "M82",
            "G1 X1 E10",  # XYZ relative (X 3 -> 4), E absolute: 10 - 6
        ),
        [
            (5, (0, 0, 0), (1, 0, 0), 2.0, 1000, "G1", "extrude"),
            (6, (1, 0, 0), (2, 0, 0), 1.0, 1000, "G1", "extrude"),
            (8, (2, 0, 0), (3, 0, 0), 3.0, 1000, "G1", "extrude"),
            (11, (3, 0, 0), (4, 0, 0), 4.0, 1000, "G1", "extrude"),
        ],
    ),
    (
        "G92 E resets absolute E, G92 XYZ shifts coordinates, bare G92 zeroes all",
        lines(
            "G28",
            "M82",
            "G92 E0",
            "G1 X10 E2 F1000",  # e 2
            "G92 E0",
            "G1 X20 E1",  # e 1, not -1
            "G92 E5",
            "G1 X30 E4",  # e -1 while moving: travel
            "G92 X100 Y100 Z1",
            "G1 X110 E4",  # no E change
            "G92",
            "G1 X1 Y1 E1",
        ),
        [
            (4, (0, 0, 0), (10, 0, 0), 2.0, 1000, "G1", "extrude"),
            (6, (10, 0, 0), (20, 0, 0), 1.0, 1000, "G1", "extrude"),
            (8, (20, 0, 0), (30, 0, 0), -1.0, 1000, "G1", "travel"),
            (10, (100, 100, 1), (110, 100, 1), 0.0, 1000, "G1", "travel"),
            (12, (0, 0, 0), (1, 1, 0), 1.0, 1000, "G1", "extrude"),
        ],
    ),
    (
        "modal feed shared by G0 and G1, NaN before the first F",
        lines(
            "G28",
            "G0 X1",
            "G1 F1500",  # feed only: a move of kind "none"
            "G0 X2",
            "G1 X3 F300",
            "G0 X4",
            "G1 X4",  # already there
        ),
        [
            (2, (0, 0, 0), (1, 0, 0), 0.0, NAN, "G0", "travel"),
            (3, (1, 0, 0), (1, 0, 0), 0.0, 1500, "G1", "none"),
            (4, (1, 0, 0), (2, 0, 0), 0.0, 1500, "G0", "travel"),
            (5, (2, 0, 0), (3, 0, 0), 0.0, 300, "G1", "travel"),
            (6, (3, 0, 0), (4, 0, 0), 0.0, 300, "G0", "travel"),
            (7, (4, 0, 0), (4, 0, 0), 0.0, 300, "G1", "none"),
        ],
    ),
    (
        "line numbers and checksums stripped, compact and lower-case words, G00/G01, CRLF",
        "N1 G28*18\r\nN2 G92 E0*69\r\nN3 G1 X5 Y5 E1 F1200*27\r\nN4 G1X10Y5E2*110\r\n"
        "g1 x10 y0 e2.5\r\nG01 X0 E3 ; trailing comment\r\nG00 Y.5\r\n",
        [
            (3, (0, 0, 0), (5, 5, 0), 1.0, 1200, "G1", "extrude"),
            (4, (5, 5, 0), (10, 5, 0), 1.0, 1200, "G1", "extrude"),
            (5, (10, 5, 0), (10, 0, 0), 0.5, 1200, "G1", "extrude"),
            (6, (10, 0, 0), (0, 0, 0), 0.5, 1200, "G1", "extrude"),
            (7, (0, 0, 0), (0, 0.5, 0), 0.0, 1200, "G0", "travel"),
        ],
    ),
    (
        "retraction with a Z hop is a retraction, Z alone is z",
        lines("G28", "M83", "G1 Z1 E-0.5 F600", "G1 Z0.2", "G1 Z0.2 E0.5"),
        [
            (3, (0, 0, 0), (0, 0, 1), -0.5, 600, "G1", "retract"),
            (4, (0, 0, 1), (0, 0, 0.2), 0.0, 600, "G1", "z"),
            (5, (0, 0, 0.2), (0, 0, 0.2), 0.5, 600, "G1", "unretract"),
        ],
    ),
    (
        "unknown (NaN) position before homing, partial homing",
        lines(
            "G1 X10 Y10 F3000",
            "G1 X20",
            "G1 E-1",  # absolute E never set: e unknown
            "G28 X",
            "G1 Y1",
            "G28",
            "G1 X5 Y5 Z1",
        ),
        [
            (1, (NAN, NAN, NAN), (10, 10, NAN), 0.0, 3000, "G1", "travel"),
            (2, (10, 10, NAN), (20, 10, NAN), 0.0, 3000, "G1", "travel"),
            (3, (20, 10, NAN), (20, 10, NAN), NAN, 3000, "G1", "none"),
            (5, (0, 10, NAN), (0, 1, NAN), 0.0, 3000, "G1", "travel"),
            (7, (0, 0, 0), (5, 5, 1), 0.0, 3000, "G1", "travel"),
        ],
    ),
]


@pytest.mark.parametrize(("text", "expected"), [c[1:] for c in MOVE_CASES], ids=[c[0] for c in MOVE_CASES])
def test_moves(text: str, expected: list[tuple]) -> None:
    assert_moves(text, expected)


@pytest.mark.parametrize(
    ("text", "mode"),
    [
        ("", "absolute"),
        ("M83", "relative"),
        ("M83\nG90", "absolute"),
        ("G91", "relative"),
        ("G91\nM82", "absolute"),
        ("M82\nG91", "relative"),
        ("G91\nM82\nG90\nM83", "relative"),
    ],
)
def test_e_mode_is_the_final_one(text: str, mode: str) -> None:
    assert read_gcode(text).e_mode == mode


def test_homing_lines_and_no_unknown_position_after_homing() -> None:
    program = read_gcode(lines("G1 X1", "G28 X0 Y0", "G1 X2", "G28", "G1 X3 Y3"))
    assert program.homed_at == [2, 4]
    assert np.isnan(program.moves[0].start).all()
    assert np.isnan(program.moves[1].start[2]) and program.moves[1].start[:2] == (0.0, 0.0)
    assert program.moves[2].start == (0.0, 0.0, 0.0)


def test_lengths_segments_and_totals() -> None:
    program = read_gcode(
        lines(
            "G28",
            "G92 E0",
            "G1 X3 Y4 E1 F600",  # xy 5
            "G1 X6 Y8 Z12 E2",  # xy 5, 3D 13
            "G1 E1",  # retract 1
            "G0 X0 Y0",
            "G1 E2",
            "G1 X1 E2.5",
        )
    )
    first, second = program.moves[:2]
    assert first.xy_length == pytest.approx(5.0) and first.length == pytest.approx(5.0)
    assert second.xy_length == pytest.approx(5.0) and second.length == pytest.approx(13.0)
    assert [m.line for m in program.extruding_moves()] == [3, 4, 8]
    assert [m.extruding for m in program.moves] == [True, True, False, False, False, True]
    assert program.total_e() == pytest.approx(2.5)
    np.testing.assert_allclose(program.segments("extrude"), [[[0, 0], [3, 4]], [[3, 4], [6, 8]], [[0, 0], [1, 0]]])
    np.testing.assert_allclose(program.segments("travel"), [[[6, 8], [0, 0]]])
    assert program.segments("retract").shape == (1, 2, 2)
    assert program.segments("z").shape == (0, 2, 2)


def test_comments_and_headers() -> None:
    program = read_gcode(
        lines(
            ";FLAVOR:Marlin",
            ";TIME:1234",
            ";Filament used: 1.5m",
            "",
            "G28 ; home all ",
            ";TIME:99",
            ";  just text  ",
            ";",
        )
    )
    assert program.comments == [
        (1, "FLAVOR:Marlin"),
        (2, "TIME:1234"),
        (3, "Filament used: 1.5m"),
        (5, "home all"),
        (6, "TIME:99"),
        (7, "just text"),
        (8, ""),
    ]
    assert program.header("TIME") == "1234"  # the first one
    assert program.header("Filament used") == "1.5m"
    assert program.header("FLAVOR") == "Marlin"
    assert program.header("LAYER_COUNT") is None
    assert program.header("just text") is None
    assert program.homed_at == [5]


def test_pauses_with_messages() -> None:
    program = read_gcode(
        lines("M0 Flip the frame about the y axis", "M1", "G28", "M0 Turn over ; then press", "m0   Keeps Case  ")
    )
    assert program.pauses == [(1, "Flip the frame about the y axis"), (2, ""), (4, "Turn over"), (5, "Keeps Case")]
    assert program.unknown == []


def test_temperatures_and_fans() -> None:
    program = read_gcode(
        lines("M140 S60", "M104 S210 T0", "M190 S60", "M109 S210", "M106", "M106 S128", "M107", "M109 R180", "M104 S0")
    )
    assert program.temperatures == [
        (1, "M140", 60.0),
        (2, "M104", 210.0),
        (3, "M190", 60.0),
        (4, "M109", 210.0),
        (8, "M109", 180.0),
        (9, "M104", 0.0),
    ]
    assert program.fans == [(5, 255.0), (6, 128.0), (7, 0.0)]
    assert program.unknown == []


def test_known_ignored_and_unknown_commands() -> None:
    ignored = read_gcode(lines("M84", "M400", "M117 Printing: side A", "M18 X Y", "G4 P500", "G4 S1", "G21", "M84 S0"))
    assert ignored.unknown == [] and ignored.moves == []
    unknown = read_gcode(lines("M105", "T0", "G29", "M851 Z-1.5", "G92.1", "M104"))
    assert unknown.unknown == [(1, "M105"), (2, "T0"), (3, "G29"), (4, "M851"), (5, "G92.1"), (6, "M104")]


@pytest.mark.parametrize(
    ("text", "line", "what"),
    [
        ("G28\nG1 X1.2.3", 2, "malformed word 'X1.2.3'"),
        ("G1 X", 1, "malformed word 'X'"),
        ("G28\n\n; comment\nG1 X1 Y", 4, "malformed word 'Y'"),
        ("G1 X-", 1, "malformed"),
        ("M106 S", 1, "malformed"),
        ("G4 Pfive", 1, "malformed"),
        ("G20", 1, "G20"),
        ("G28\nG21\nG20\nG1 X1", 3, "G20"),
        ("N1 G28*19", 1, "checksum"),
        ("G28\nN2 G1 X1*", 2, "checksum"),
        ("G1 X1 Q3", 1, "does not take Q"),
        ("G1 X1 X2", 1, "twice"),
        ("G1 X1 Y2 10", 1, "unexpected text"),
        ("G1 X 10", 1, "malformed word 'X'"),
        ("G28\nhello", 2, "no G, M or T command"),
        ("X10 Y10", 1, "no G, M or T command"),
        ("G1 X1 F0", 1, "feed"),
    ],
)
def test_errors_name_the_line(text: str, line: int, what: str) -> None:
    with pytest.raises(ValueError, match=rf"^line {line}:") as error:
        read_gcode(text)
    assert what in str(error.value)


def test_no_exponents_a_glued_e_is_the_e_axis() -> None:
    """Marlin reads "X1e-05" as X1 E-05: a float printed by Python's repr would silently retract 5 mm."""
    (move,) = read_gcode(lines("G28", "M83", "G1 X1e-05")).moves
    assert move.end == (1.0, 0.0, 0.0) and move.e == -5.0


def test_reader_is_independent_of_ribbond() -> None:
    from pathlib import Path

    source = (Path(__file__).parent / "reader.py").read_text()
    assert "ribbond" not in source.replace("`ribbond.gcode`", "").replace("`ribbond`", "")
