"""The one G-code check (``ribbond.gcode.checker``) in process, fast: each rule of its docstring on a
profile whose frame is neither square nor centred on the origin (so X's bound cannot stand in for Y's),
expectations from the profile and from Marlin's semantics (issue 35: the mutation run's tests)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ribbond.design.format import StitchMark
from ribbond.gcode.checker import (Checked, GcodeChecker, Modal, check_stitch_marks, extruded_segments,
                                   parse_command, uncovered)
from ribbond.gcode.profiles import FrameSpec, Motion, PrinterProfile, Temperatures

#: The frame: x 40 to 160, y 40 to 80 (120 x 40 mm around (100, 60)).
X0, X1, Y0, Y1 = 40.0, 160.0, 40.0, 80.0
FABRIC = 1.5
PROFILE = PrinterProfile(
    name="test", frame=FrameSpec(center=(100.0, 60.0), size=(120.0, 40.0)),
    temperatures=Temperatures(nozzle=200.0, bed=0.0, nozzle_max=240.0, bed_max=90.0),
    motion=Motion(max_xy_speed=100.0, max_z_speed=5.0, max_e_speed=20.0, travel_speed=100.0, z_speed=5.0,
                  retract_speed=20.0),
    layers={"fabric_z": FABRIC})
HOME = ["G28", f"G0 X{X0 + 10:g} Y{Y0 + 10:g} Z{FABRIC + 5:g}"]


def run(*lines: str) -> Checked:
    return GcodeChecker(PROFILE).check(list(lines))


def refused(*lines: str) -> str:
    with pytest.raises(ValueError) as info:
        run(*lines)
    return str(info.value)


# ---------------------------------------------------------------------------------- parsing


@pytest.mark.parametrize(("command", "code", "args"), [
    ("G1 X1 Y2", "G1", {"X": 1.0, "Y": 2.0}),
    ("g01x1.5y-2", "G1", {"X": 1.5, "Y": -2.0}),
    ("N12 G28 X*71", "G28", {"X": None}),
    ("  M104 S200  ", "M104", {"S": 200.0}),
    ("G29.1 Z3", "G29.1", {"Z": 3.0}),
    ("M117 hello X1 world", "M117", {}),
    ("T1", "T1", {}),
])
def test_parse_command_reads_as_marlin_does(command: str, code: str, args: dict) -> None:
    assert parse_command(command, "here") == (code, args)


@pytest.mark.parametrize(("command", "named"), [
    ("X10", "'X10' is not a G-code command"),
    ("", "'' is not a G-code command"),
    ("G1 X1.2.3", "'X1.2.3' is not a letter and a number"),
    ("G1 X" + "9" * 400, "is not a finite number"),   # (letters split words: only many digits overflow)
    ("G1 X1 #", "'X1 #' is not a list of words"),
])
def test_parse_command_names_what_is_wrong_and_where(command: str, named: str) -> None:
    with pytest.raises(ValueError) as info:
        parse_command(command, "console, line 3")
    assert str(info.value).startswith("console, line 3: ") and named in str(info.value)


# ---------------------------------------------------------------------------------- the frame


@pytest.mark.parametrize(("x", "y"), [(X0, Y0), (X1, Y1), (X0, Y1), (X1, Y0), (100.0, 60.0)])
def test_a_move_to_the_frames_edge_is_allowed(x: float, y: float) -> None:
    checked = run("G28", f"G0 Z{FABRIC + 2:g}", f"G0 X{x:g} Y{y:g}")
    assert checked.modal.known() == (x, y, FABRIC + 2)


@pytest.mark.parametrize(("x", "y"), [(X0 - 0.01, 60.0), (X1 + 0.01, 60.0), (100.0, Y0 - 0.01),
                                      (100.0, Y1 + 0.01),
                                      (100.0, 120.0),      # inside X's range, outside Y's (a square check misses it)
                                      (100.0, 20.0)])
def test_a_move_outside_the_frame_is_refused_naming_both_ranges(x: float, y: float) -> None:
    message = refused("G28", f"G0 Z{FABRIC + 2:g}", f"G0 X{x:g} Y{y:g}")
    assert message == (f"program, line 3: the move ends at x {x:g}, y {y:g}, outside the frame "
                       f"(x {X0:g} to {X1:g}, y {Y0:g} to {Y1:g} mm)")


def test_only_the_axes_a_move_names_are_checked_against_the_frame() -> None:
    # homed to 0, 0 (outside the frame): a Z move alone is fine, an X move alone must land inside in X
    up = ("G28", f"G0 Z{FABRIC + 1:g}")
    assert run(*up, f"G0 X{X0:g}").modal.pos[:2] == [X0, 0.0]
    assert "outside the frame" in refused(*up, f"G0 Y{Y0 - 1:g}")


def test_a_move_below_the_fabric_is_refused_and_onto_it_allowed() -> None:
    assert run(*HOME, f"G1 Z{FABRIC:g}").modal.pos[2] == FABRIC
    assert refused(*HOME, f"G1 Z{FABRIC - 0.01:g}") == (
        f"program, line 3: the move goes down to z {FABRIC - 0.01:g}, below the fabric (z {FABRIC:g} mm)")


def test_relative_moves_are_followed_from_the_known_position() -> None:
    checked = run(*HOME, "G91", "G1 X5 Y-2 Z1", "G90")
    assert checked.modal.known() == (X0 + 15, Y0 + 8, FABRIC + 6)
    assert "outside the frame" in refused(*HOME, "G91", f"G1 Y{Y1 - Y0:g}")   # Y0+10 + 40 > Y1


def test_a_move_from_an_unknown_position_is_refused() -> None:
    assert refused("G0 X50") == ("program, line 1: the head's Y, Z position is not known, so where this move "
                                 "goes cannot be checked; home first (G28, or ribbonctl home) or give X, Y and Z")
    assert "relative X move before the X position is known" in refused("G91", "G1 X1")
    run(f"G0 X50 Y50 Z{FABRIC + 1:g}")                  # all three given: known
    assert run("G1 E1 F100").modal.known() is None       # no axis moved: nothing to check


def test_homing_some_axes_and_motors_off() -> None:
    assert run("G28 X").modal.pos == [0.0, None, None]
    modal = run("G28", "M84 X").modal
    assert modal.pos == [None, 0.0, 0.0] and modal.motors_off and modal.homed
    assert run("G28", "M18").modal.pos == [None, None, None]
    assert run("G28", "M84 E").modal.pos == [0.0, 0.0, 0.0]       # the extruder's motor only
    assert run("G28", "M84 S30").modal.pos == [0.0, 0.0, 0.0]     # S sets the idle timeout only
    assert not run("G28").modal.motors_off and not Modal().homed


# ---------------------------------------------------------------------------------- temperatures


@pytest.mark.parametrize("code", ["M104", "M109", "M140", "M190"])
@pytest.mark.parametrize("letter", ["S", "R", "B"])
def test_every_temperature_word_of_every_heater_command_is_limited(code: str, letter: str) -> None:
    limit, name = ((PROFILE.temperatures.nozzle_max, "nozzle_max") if code in ("M104", "M109")
                   else (PROFILE.temperatures.bed_max, "bed_max"))
    run(f"{code} {letter}{limit:g}", f"{code} {letter}0")
    heater = "nozzle" if name == "nozzle_max" else "bed"
    assert refused(f"{code} {letter}{limit + 0.5:g}") == (
        f"program, line 1: {heater} {limit + 0.5:g} °C is above the profile's {name} ({limit:g} °C)")
    assert refused(f"{code} {letter}-1") == (
        f"program, line 1: {heater} -1 °C: a temperature must be 0 °C (off) or more")


def test_a_heater_command_checks_every_word_not_only_the_first() -> None:
    assert "above the profile's nozzle_max" in refused("M104 S200 B300")
    assert "above the profile's nozzle_max" in refused("M109 S200 R300")


def test_a_material_preset_is_refused_on_heater_commands_only() -> None:
    assert refused("M104 I1") == "program, line 1: M104 I… sets a material preset the check cannot see; give S…"
    run("M303 E0 S200 C3 I1")  # M303's I is not a preset (the tuning heater index in some firmware)


@pytest.mark.parametrize(("command", "limit_name"), [("M303 S250", "nozzle_max"), ("M303 E0 S250", "nozzle_max"),
                                                     ("M303 E1 S250", "nozzle_max"),
                                                     ("M303 E-1 S95", "bed_max")])
def test_pid_autotune_is_limited_by_its_heater(command: str, limit_name: str) -> None:
    assert f"above the profile's {limit_name}" in refused(command)
    run(command.replace("S250", "S240").replace("S95", "S90"))


def test_pid_autotune_of_an_unknown_heater_is_refused() -> None:
    assert refused("M303 E-2 S50") == "program, line 1: M303 E-2 tunes a heater the profile has no limit for"


# ---------------------------------------------------------------------------------- refused commands


@pytest.mark.parametrize(("command", "why"), [
    ("G2 X10 Y10 I5", "G2 arcs are not checked against the frame; convert them to G1 moves"),
    ("G3 X10 Y10 I5", "G3 arcs are not checked"),
    ("G20", "G20 (inches) is not supported; the profile's limits are in mm"),
    ("G92 X0", "G92 redefines the X/Y/Z position"), ("G92 Y0", "G92 redefines"), ("G92 Z0", "G92 redefines"),
    ("G92", "G92 redefines"),
    ("G29", "G29 is not a command the check follows"), ("G30", "G30 is not a command the check follows"),
    ("M48", "M48 probes the bed (the nozzle would go down into the fabric); not allowed on the fabric"),
    ("M48 P3", "M48 probes the bed"), ("M600", "M600 parks the head"), ("M290 Z-1", "M290 babysteps"),
    ("M92 X80", "M92 changes steps per mm"), ("M203 X900", "M203 raises"), ("M206 X5", "M206 moves"),
    ("M211 S0", "M211 switches"), ("M24", "M24 starts a print from the SD card"),
    ("M220 S101", "M220 S101 sets the feed override above 100 %"),
])
def test_what_would_escape_the_check_is_refused(command: str, why: str) -> None:
    assert why in refused(command)


@pytest.mark.parametrize("command", ["G92 E0", "M220 S100", "M220", "G4 P100", "G21", "G90", "M82", "M83",
                                     "M106 S128", "M107", "M117 G2 X1", "M400", "M114", "T0"])
def test_what_the_check_follows_or_cannot_move_the_head_passes_unchanged(command: str) -> None:
    assert run(command).commands == [command]


# ---------------------------------------------------------------------------------- the modal state


def test_g90_g91_set_e_mode_and_m82_m83_only_e() -> None:
    modal = run("G91")
    assert (modal.modal.absolute, modal.modal.e_absolute) == (False, False)
    modal = run("G91", "G90")
    assert (modal.modal.absolute, modal.modal.e_absolute) == (True, True)
    modal = run("M83")
    assert (modal.modal.absolute, modal.modal.e_absolute) == (True, False)
    assert run("M83", "M82").modal.e_absolute
    assert run("G92 E5").modal.e == 5.0
    assert run("G92 E5", "G1 E7").modal.e == 7.0
    assert run("M83", "G1 E7").modal.e is None


def test_a_move_word_the_check_does_not_know_is_refused() -> None:
    assert refused(*HOME, "G1 X50 A3") == ("program, line 3: 'A' is not a letter and a number a move takes "
                                           "(X, Y, Z, E and F, each with its number)")
    assert "'X' is not a letter and a number a move takes" in refused(*HOME, "G1 X")


def test_a_feed_of_zero_or_less_is_refused() -> None:
    assert refused(*HOME, "G1 X60 F0") == "program, line 3: feed F0: a feed rate must be above 0 mm/min"
    assert "F-5" in refused(*HOME, "G1 X60 F-5")


# ---------------------------------------------------------------------------------- feed clamping (Marlin)


def test_an_xy_move_above_the_xy_maximum_is_clamped_to_it() -> None:
    checked = run(*HOME, "G1 X80 F9000")            # 150 mm/s asked, X and Y at most 100 mm/s
    assert checked.commands[-1] == "G1 X80 F6000"
    assert checked.clamped == {"X": 1} and checked.first_clamped == 3
    assert checked.notes(PROFILE) == ["1 move's feed rate clamped to the profile (X ≤ 100 mm/s), as the firmware "
                                      "limits feed rates; the first at line 3"]


def test_a_diagonal_move_is_clamped_by_the_faster_axis_share() -> None:
    # Z from 6.5 to 9.5 (3 mm) while X moves 4 mm: path 5 mm, Z's share 3/5, Z at most 5 mm/s -> 25/3 mm/s
    checked = run(*HOME, f"G1 X{X0 + 14:g} Z{FABRIC + 8:g} F6000")
    allowed = 5.0 * 5 / 3 * 60
    assert checked.commands[-1] == f"G1 X{X0 + 14:g} Z{FABRIC + 8:g} F{math.floor(allowed * 10) / 10:g}"
    assert checked.clamped == {"Z": 1}


def test_the_next_move_gets_the_feed_asked_for_again_after_a_clamp() -> None:
    checked = run(*HOME, "G1 Z9 F6000", "G1 X60", "G1 X70")
    assert checked.commands[-3:] == ["G1 Z9 F300", "G1 X60 F6000", "G1 X70"]
    assert checked.notes(PROFILE, unit="command") == [
        "1 move's feed rate clamped to the profile (Z ≤ 5 mm/s), as the firmware limits feed rates; "
        "the first at command 3"]


def test_several_clamps_are_counted_and_the_first_is_named() -> None:
    checked = run(*HOME, "G1 X60 F600", "G1 Z9 F6000", "G1 Z12", "G1 X70 F9000")
    assert checked.clamped == {"Z": 2, "X": 1} and checked.first_clamped == 4
    assert checked.notes(PROFILE) == ["3 moves' feed rates clamped to the profile (X ≤ 100 mm/s, Z ≤ 5 mm/s), "
                                      "as the firmware limits feed rates; the first at line 4"]
    assert run(*HOME, "G1 X60 F600").notes(PROFILE) == []


def test_an_extrusion_only_move_is_clamped_by_e() -> None:
    checked = run(*HOME, "M83", "G1 E5 F3000")        # 50 mm/s of filament, E at most 20
    assert checked.commands[-1] == "G1 E5 F1200" and checked.clamped == {"E": 1}


def test_a_move_along_an_unknown_axis_is_clamped_by_the_slowest_named_axis() -> None:
    checked = run(*HOME, "G1 E5 F3000")               # E's start is not known (absolute E, no G92)
    assert checked.commands[-1] == "G1 E5 F1200" and checked.clamped == {"E": 1}
    checked = run("G1 E5 F3000")                      # nor X, Y, Z: the slowest of all four, Z
    assert checked.commands == ["G1 E5 F300"] and checked.clamped == {"Z": 1}


def test_a_move_without_a_known_feed_is_left_to_the_firmware() -> None:
    assert run(*HOME, "G1 Z20").commands[-1] == "G1 Z20"
    assert run(*HOME, "G1 X50 F600", "G1 X50 F99999").commands[-1] == "G1 X50 F99999"   # no motion: no limit


def test_lines_keep_their_comments_and_blank_lines() -> None:
    checked = run("G28 ; home", "", "; only a comment", "N5 G0 X50 Y50 Z9 F9000*12 ; fast")
    path = math.sqrt(50 ** 2 + 50 ** 2 + 9 ** 2)         # from (0, 0, 0): Z's 9 mm at most 5 mm/s
    feed = f"{math.floor(5.0 * path / 9 * 60 * 10) / 10:g}"
    assert checked.commands == ["G28", f"G0 X50 Y50 Z9 F{feed}"]
    assert checked.lines[:3] == ["G28 ; home", "", "; only a comment"]
    assert checked.lines[3] == f"G0 X50 Y50 Z9 F{feed}  ; fast"


def test_a_refusal_names_the_source_and_line() -> None:
    with pytest.raises(ValueError, match=r"^upload\.gcode, line 2: "):
        GcodeChecker(PROFILE, "upload.gcode").check(["G28", "G2 X1"])
    with pytest.raises(ValueError, match=r"^console: G2"):
        GcodeChecker(PROFILE, where=lambda _n, command: f"console: {command.split()[0]}").check(["G2 X1"])


def test_the_modal_state_carries_over_between_batches() -> None:
    first = GcodeChecker(PROFILE).check(HOME)
    second = GcodeChecker(PROFILE, modal=first.modal).check(["G91", "G1 X1"])
    assert second.modal.known() == (X0 + 11, Y0 + 10, FABRIC + 5)
    checker = GcodeChecker(PROFILE)
    earlier = checker.check(HOME)
    checker.check(["G1 X60"])
    assert earlier.modal.known() == (X0 + 10, Y0 + 10, FABRIC + 5)   # a result keeps the state it ended in


def test_extruded_segments_are_the_printing_moves_in_xy() -> None:
    lines = [*HOME, "G92 E0", "G1 X60 E1", "G1 X70", "G1 Y60 E2", "G1 Z9 E3", "M83", "G1 X80 E0.5",
             "G1 X90 E-0.5", "M117 X1"]
    segments = extruded_segments(lines, PROFILE)
    assert segments.tolist() == [[[50.0, 50.0], [60.0, 50.0]], [[70.0, 50.0], [70.0, 60.0]],
                                 [[70.0, 60.0], [80.0, 60.0]]]
    assert extruded_segments([], PROFILE).shape == (0, 2, 2)
    with pytest.raises(ValueError, match="line 3: .*outside the frame"):
        extruded_segments([*HOME, "G1 X500 E1"], PROFILE)


def test_the_position_is_known_only_with_all_three_axes() -> None:
    assert Modal(pos=[1.0, 2.0, 3.0]).known() == (1.0, 2.0, 3.0)
    for pos in ([None, 2.0, 3.0], [1.0, None, 3.0], [1.0, 2.0, None]):
        assert Modal(pos=pos).known() is None


def test_a_lower_case_move_is_clamped_as_marlin_reads_it() -> None:
    assert run(*HOME, "g1 x80 f9000").commands[-1] == "g1 x80 F6000"


def test_everything_after_the_first_star_is_the_checksum() -> None:
    assert run("N3 G28*100*7").commands == ["G28"]


def test_a_rewritten_line_keeps_its_whole_comment_and_a_line_without_one_gets_none() -> None:
    checked = run(*HOME, "G1 X80 F9000 ; fast ; really  \r\n", "G1 X90 F9000")
    assert checked.lines[-2:] == ["G1 X80 F6000  ; fast ; really  ", "G1 X90 F6000"]


# ---------------------------------------------------------------------------------- stitch marks (issue 26)


def test_samples_along_a_polyline_keep_its_vertices_and_the_step() -> None:
    from ribbond.gcode.checker import _samples
    stroke = np.array([[0.0, 0.0], [0.1, 0.0], [1.0, 0.0]])
    assert _samples(stroke, 0.5).tolist() == [[0.0, 0.0], [0.1, 0.0], [0.55, 0.0], [1.0, 0.0]]


def test_uncovered_points_are_those_farther_than_reach_from_every_segment() -> None:
    stroke = np.array([[0.0, 0.0], [10.0, 0.0]])
    half = np.array([[[0.0, 0.0], [5.0, 0.0]]])
    assert uncovered(stroke, np.array([[[0.0, 0.0], [10.0, 0.0]]]), 0.4).shape == (0, 2)
    assert uncovered(stroke, half, 0.4)[:, 0] == pytest.approx([5.6 + 0.4 * k for k in range(12)])
    assert uncovered(stroke, np.zeros((0, 2, 2)), 0.4).shape == (26, 2)


@pytest.mark.parametrize("side", [-0.5, 0.5])
def test_a_point_exactly_reach_from_a_segment_is_covered(side: float) -> None:
    stroke = np.array([[0.0, 0.0], [0.0, 1.0]])
    assert uncovered(stroke, np.array([[[side, 0.0], [side, 1.0]]]), 0.5).shape == (0, 2)


def test_a_point_beyond_a_segments_end_is_measured_to_the_end_not_the_line() -> None:
    segment = np.array([[[0.0, 0.0], [1.0, 0.0]]])
    assert uncovered(np.array([[-2.0, 0.0], [1.0, 0.0]]), segment, 0.5)[:, 0].tolist() == [-2.0, -1.5, -1.0]
    assert uncovered(np.array([[0.0, 0.0], [3.0, 0.0]]), segment, 0.5)[:, 0].tolist() == [2.0, 2.5, 3.0]


def test_a_short_segment_covers_its_own_length() -> None:
    short = np.array([[0.0, 0.0], [0.5, 0.0]])
    assert uncovered(short, short[None], 0.2).shape == (0, 2)


def test_a_stitch_mark_must_be_printed_within_half_the_nozzle_width() -> None:
    nozzle = PROFILE.extruder.nozzle_diameter
    mark = StitchMark(label="A1", seam="A", at=(60.0, 50.0), outward=(0.0, 1.0),
                      strokes=[[(60.0, 50.0), (60.0, 55.0)], [(62.0, 52.0), (63.0, 52.0)]])
    tick = [*HOME, "G92 E0", "G1 X60 Y50", "G1 Y55 E1"]
    label = [f"G1 X62 Y{52 + 0.49 * nozzle:g}", f"G1 X63 E2"]
    check_stitch_marks([*tick, *label], [mark], PROFILE)
    with pytest.raises(ValueError) as info:
        check_stitch_marks(tick, [mark], PROFILE, source="front.gcode")
    assert str(info.value) == (f"front.gcode does not print stroke 1 of stitch mark A1 (its label): nothing "
                               f"printed within {0.5 * nozzle:g} mm of (62.000, 52.000)")
    far = [f"G1 X62 Y{52 + 0.51 * nozzle:g}", "G1 X63 E2"]
    with pytest.raises(ValueError, match=r"stroke 1 of stitch mark A1 \(its label\)"):
        check_stitch_marks([*tick, *far], [mark], PROFILE)
    with pytest.raises(ValueError, match=r"stroke 0 of stitch mark A1 \(the tick\)"):
        check_stitch_marks(["G28"], [mark], PROFILE)
    with pytest.raises(ValueError, match=r"^front\.gcode, line 3: .*outside the frame"):
        check_stitch_marks([*HOME, "G1 X500"], [mark], PROFILE, source="front.gcode")


# ---------------------------------------------------------------------------------- the tolerances (1e-6)


def test_limits_hold_to_a_millionth_and_not_beyond() -> None:
    eps = 1e-6
    run(f"M104 S{240.0 + eps!r}")                                   # within the tolerance: at the limit
    assert "above the profile's nozzle_max" in refused(f"M104 S{240.0 + 3 * eps!r}")
    for x, y in ((X0 - eps, Y0 - eps), (X1 + eps, Y1 + eps)):
        run("G28", f"G0 Z{FABRIC + 2:g}", f"G0 X{x!r} Y{y!r}")
    for x, y in ((X0 - 3 * eps, 60.0), (X1 + 3 * eps, 60.0), (100.0, Y0 - 3 * eps), (100.0, Y1 + 3 * eps)):
        assert "outside the frame" in refused("G28", f"G0 Z{FABRIC + 2:g}", f"G0 X{x!r} Y{y!r}")
    run(*HOME, f"G1 Z{FABRIC - eps!r}")
    assert "below the fabric" in refused(*HOME, f"G1 Z{FABRIC - 3 * eps!r}")


def test_a_millionth_of_filament_is_no_motion() -> None:
    assert run(*HOME, "M83", "G1 E0.000001 F3000").commands[-1] == "G1 E0.000001 F3000"


def test_a_slow_feed_is_a_feed() -> None:
    assert run(*HOME, "G1 X60 F0.5").commands[-1] == "G1 X60 F0.5"


def test_a_move_that_states_its_own_feed_is_sent_as_written() -> None:
    assert run(*HOME, "G1 F600.0 X60").commands[-1] == "G1 F600.0 X60"


def test_a_move_from_an_unknown_start_to_a_known_end_is_clamped_by_the_slowest_axis() -> None:
    checked = run(f"G0 X50 Y50 Z{FABRIC + 1:g} F99999")
    assert checked.commands == [f"G0 X50 Y50 Z{FABRIC + 1:g} F300"] and checked.clamped == {"Z": 1}


def test_filament_is_not_part_of_the_path_length() -> None:
    # X 30 mm with 10 mm of filament: X alone would allow 100 mm/s; E at 20 mm/s allows 30/10 * 20 = 60
    checked = run(*HOME, "M83", "G1 X80 E10 F9000")
    assert checked.commands[-1] == "G1 X80 E10 F3600" and checked.clamped == {"E": 1}


def test_a_relative_move_before_the_position_is_known_is_refused_naming_it() -> None:
    assert refused("G91", "G1 Y1") == ("program, line 2: a relative Y move before the Y position is known; "
                                       "home (G28) or move to an absolute position first")


# ---------------------------------------------------------------------------------- the second mutation run


def test_absolute_filament_is_measured_from_where_it_stands() -> None:
    # E from 5 to 15 is 10 mm of filament (not 15, not 20): E at 20 mm/s allows 30/10 * 20 = 60 mm/s
    assert run(*HOME, "G92 E5", "G1 X80 E15 F9000").commands[-1] == "G1 X80 E15 F3600"


def test_a_comment_ending_in_a_letter_is_kept_whole() -> None:
    assert run(*HOME, "G1 X80 F9000 ; to X").lines[-1] == "G1 X80 F6000  ; to X"


def test_extruded_segments_read_numbered_lower_case_and_absolute_lines_as_marlin_does() -> None:
    lines = [*HOME, "N7 G1 X60 E1*45",            # numbered, E from unknown: not known to feed
             "G92 E5", "g1 x70 e5.5",            # lower case, 0.5 mm fed
             "G1 X75 E5.5",                      # absolute E unchanged: a travel
             "M83", "G1 X80 E0.000001",          # a millionth of filament: nothing fed
             "G1 X85 E0.1"]
    assert extruded_segments(lines, PROFILE).tolist() == [[[60.0, 50.0], [70.0, 50.0]], [[80.0, 50.0], [85.0, 50.0]]]
    assert extruded_segments(["G1 X50 Y50 Z3 E1"], PROFILE).shape == (0, 2, 2)   # absolute E, start unknown


def test_extruded_segments_need_a_known_start_in_xy_only() -> None:
    assert extruded_segments(["M83", "G1 X50 Y50 Z3 E1"], PROFILE).shape == (0, 2, 2)     # from nowhere known
    segments = extruded_segments(["G28 X Y", "M83", "G1 X50 Y50 Z3 E1"], PROFILE)        # Z unknown, XY known
    assert segments.tolist() == [[[0.0, 0.0], [50.0, 50.0]]]


def test_extruded_segments_name_the_program_in_refusals() -> None:
    with pytest.raises(ValueError, match=r"^program, line 1: G2 arcs"):
        extruded_segments(["G2 X1"], PROFILE)


# ---------------------------------------------------------------------------------- the third mutation run


@pytest.mark.parametrize(("command", "code", "args"), [
    ("N3 G28*100*7", "G28", {}),               # the checksum starts at the first star
    ("M117.1 Hello World", "M117.1", {}),      # a subcode of a text command is text too
])
def test_parse_command_edge_cases(command: str, code: str, args: dict) -> None:
    assert parse_command(command, "here") == (code, args)


def test_a_line_that_is_not_a_command_is_named_by_its_first_word_and_its_place() -> None:
    assert refused("X10 Y5") == "program, line 1: 'X10' is not a G-code command (G…, M… or T…)"


def test_the_refusals_say_why_and_what_to_do() -> None:
    assert refused("G92 X0") == ("program, line 1: G92 redefines the X/Y/Z position, which the frame check cannot "
                                 "follow (G92 E… is fine)")
    assert refused("G29") == ("program, line 1: G29 is not a command the check follows (it may move the head where "
                              "the frame and fabric check cannot see); send G0/G1 moves instead")
    assert refused("M220 S101") == ("program, line 1: M220 S101 sets the feed override above 100 % (the profile's "
                                    "adjust.speed_percent is 25-100 %), so moves would run faster than the "
                                    "profile's limits allow")
    assert "M48 probes the bed" in refused("M48.1")     # a subcode of a refused command is refused
    run(f"M220 S{100 + 1e-6!r}")                          # 100 % within the tolerance


def test_only_g92_sets_the_filament_position() -> None:
    # M201 E… (an acceleration) must not be read as the E position: E from 0 to 10 is 10 mm
    assert run(*HOME, "G92 E0", "M201 E1000", "G1 X80 E10 F9000").commands[-1] == "G1 X80 E10 F3600"


def test_a_g0_that_extrudes_prints() -> None:
    assert extruded_segments([*HOME, "M83", "G0 X60 E1"], PROFILE).tolist() == [[[50.0, 50.0], [60.0, 50.0]]]
