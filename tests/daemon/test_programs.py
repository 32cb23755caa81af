"""Programs as G-code: the time line (the programs' own estimate, ribbons, where printing starts)
and the line-by-line check of plain G-code against the printer profile. Expectations from the
geometry of the moves and from the profile's numbers."""

from __future__ import annotations

import pytest

from ribbond.daemon.components.programs import check_plain_program, check_program, program_timeline
from ribbond.gcode.profiles import load_profile
from tests.gcode.reader import read_gcode

PROFILE = load_profile("ultimaker2-tpu")
X0, Y0, X1, Y1 = PROFILE.frame.bounds
NOZZLE_MAX, BED_MAX = PROFILE.temperatures.nozzle_max, PROFILE.temperatures.bed_max
MO = PROFILE.motion
#: Each axis' maximum speed, mm/s (Marlin's max feed rate per axis).
LIMITS = {"X": MO.max_xy_speed, "Y": MO.max_xy_speed, "Z": MO.max_z_speed, "E": MO.max_e_speed}


def test_a_slow_long_move_takes_its_length_over_its_feed() -> None:
    """100 mm at 10 mm/s: 10 s, plus what accelerating to 10 mm/s and back costs (v²/a)."""
    lines = ["G28", "M109 S200", "G90", "G1 X100 F600", "M104 S0"]
    tl = program_timeline(lines, PROFILE)
    v, a = 10.0, PROFILE.motion.acceleration
    assert tl.total == pytest.approx(100 / v + v / a, abs=1e-6)
    assert tl.done_s(0) == 0.0 and tl.done_s(2) == 0.0          # homing and heating count nothing
    assert tl.done_s(4) == tl.done_s(5) == pytest.approx(tl.total)
    assert tl.first == 2                                        # printing starts after the M109
    assert tl.ribbons == 0 and tl.ribbon_at(5) == 0


def test_ribbon_comments_number_the_commands_and_the_first_part_starts_the_print() -> None:
    lines = ["; header", "G90", "M109 S225", "G0 Z2 F1200", ";TYPE:REGISTRATION 0", "G1 X30 Y30 E1 F900",
             ";TYPE:RIBBON 5 (1 of 2)", "G1 X40 Y30 E1", "G1 X50 Y30 E1", ";TYPE:RIBBON 2 (2 of 2)",
             "G1 X60 Y30 E1", "M104 S0"]
    tl = program_timeline(lines, PROFILE)
    assert len(tl.at) == 8 and tl.ribbons == 2
    assert tl.first == 3                                        # the commands before the first ;TYPE:
    assert [tl.ribbon_at(n) for n in range(1, 9)] == [0, 0, 0, 0, 1, 1, 2, 2]
    assert list(tl.at) == sorted(tl.at)


def test_a_program_inside_the_frame_passes_and_gives_its_commands() -> None:
    lines = ["; purge", "G28", "M104 S200", "M109 S200", "G90", "G0 Z5 F600", f"G0 X{X0 + 5} Y{Y0 + 5} F6000",
             "G91", "G1 X10 E1 F900", "G90", "G92 E0", "N12 G1 Y40*57", "M104 S0"]
    assert check_program(lines, PROFILE, "p.gcode") == [
        "G28", "M104 S200", "M109 S200", "G90", "G0 Z5 F600", f"G0 X{X0 + 5} Y{Y0 + 5} F6000", "G91",
        "G1 X10 E1 F900", "G90", "G92 E0", "G1 Y40", "M104 S0"]


@pytest.mark.parametrize("body, line, words", [
    (["G28", "G90", f"G0 X{X1 + 0.01} Y{Y0 + 5}"], 3, f"outside the frame (x {X0:g} to {X1:g}"),
    (["G28", "G90", f"G0 X{X0 + 5} Y{Y0 - 1}"], 3, "outside the frame"),
    (["G28", "G90", f"G0 X{X0 + 5} Y{Y0 + 5}", "G91", f"G0 X{X1}"], 5, "outside the frame"),
    (["G28", "G90", "G0 Z-0.1"], 3, "below the fabric"),
    # every bound of the frame, each axis (issue 22, item 11: only X was tried)
    (["G28", "G90", f"G0 X{X0 - 0.01} Y{Y0 + 5}"], 3, "outside the frame"),
    (["G28", "G90", f"G0 X{X0 + 5} Y{Y1 + 0.01}"], 3, "outside the frame"),
    (["G28", "G90", f"G0 Y{Y1 + 0.01}"], 3, "outside the frame"),
    (["G28", "G90", "G1 Z5 F600", f"G0 X{X0 + 5} Y{Y0 + 5}", "G91", f"G0 Y{Y1 - Y0}"], 6, "outside the frame"),
    (["G28", "G90", "G1Z-2F600"], 3, "below the fabric"),         # words without spaces, as Marlin reads them
    (["G28", "G90", "G01 Z-1"], 3, "below the fabric"),
    (["G28", "G91", "G1 Z-0.5"], 3, "below the fabric"),
    # every heater command, every temperature word
    *[([f"{code} {word}{limit + 1:g}"], 1, name)
      for code, limit, name in (("M104", NOZZLE_MAX, "nozzle_max"), ("M109", NOZZLE_MAX, "nozzle_max"),
                                ("M140", BED_MAX, "bed_max"), ("M190", BED_MAX, "bed_max"))
      for word in "SR"],
    ([f"M303 E0 S{NOZZLE_MAX + 1:g} C3"], 1, "nozzle_max"),
    ([f"M303 E-1 S{BED_MAX + 1:g} C3"], 1, "bed_max"),
    (["M104 S-5"], 1, "must be 0 °C (off) or more"),
    (["M141 S40"], 1, "chamber"),
    # moves the check cannot follow, settings that would defeat the limits
    (["G28", "G29"], 2, "G29 is not a command the check follows"),
    (["G28", "G30"], 2, "G30 is not a command the check follows"),
    (["G28", "M203 Z100"], 2, "M203 raises the firmware's maximum feed rates"),
    (["G28", "M220 S150"], 2, "feed override above 100 %"),
    (["G28", "M290 Z-0.5"], 2, "M290 babysteps"),
    (["G28", "M211 S0"], 2, "software endstops"),
    (["G28", "G92"], 2, "G92"),
    # a move from a position the check does not know
    (["G90", f"G0 X{X0 + 5} Y{Y0 + 5}"], 2, "the head's Z position is not known"),
    (["G28", "M84", "G91", "G0 Z5"], 4, "before the Z position is known"),
    (["G28", "G1 F-100 X30"], 2, "above 0 mm/min"),
    (["G91", "G0 X5"], 2, "before the X position is known"),
    (["G28", "G3 X30 Y30 I5 J0"], 2, "arcs"),
    (["G20"], 1, "inches"),
    (["G28", "G92 X10"], 2, "G92"),
    (["G28", "M112"], 2, "M112"),
    (["G28", "G1 X1a"], 2, "not a letter and a number"),
    (["; nothing"], None, "no G-code commands"),
])
def test_a_refusal_names_the_line_and_what_is_wrong(body: list[str], line: int | None, words: str) -> None:
    with pytest.raises(ValueError) as err:
        check_program(["; comment first"] + body, PROFILE, "bad.gcode")
    message = str(err.value)
    if line is not None:
        assert message.startswith(f"bad.gcode, line {line + 1}: "), message
    assert words in message, message


def test_the_heater_and_frame_limits_themselves_pass() -> None:
    """At each limit exactly: accepted (the refusals above are not of everything)."""
    lines = ["G28", f"M104 S{NOZZLE_MAX:g}", f"M109 R{NOZZLE_MAX:g}", f"M140 S{BED_MAX:g}", f"M190 S{BED_MAX:g}",
             "G90", f"G0 Z{PROFILE.layers.fabric_z:g}", f"G0 X{X0:g} Y{Y0:g}", f"G0 X{X1:g} Y{Y1:g}", "M220 S100"]
    assert check_program(lines, PROFILE, "edge.gcode") == lines


#: A slicer's start (PrusaSlicer / Cura style) and a few moves: Z lifts at F6000, a fast diagonal,
#: a fast retraction, moves relying on the modal feed after a clamped one.
SLICER = f"""; generated by PrusaSlicer-like
M140 S0
M104 S215 ; set temperature
G28 ; home all axes
G1 Z15.0 F6000 ; lift nozzle
M109 S215 ; wait for temperature
G92 E0
G1 X{X0 + 10:g} Y{Y0 + 10:g} F9000
G1 Z0.3 F6000
G1 X{X0 + 60:g} Y{Y0 + 10:g} E5 F1200
G1 X{X0 + 60:g} Y{Y0 + 60:g} E10
G1 E8 F4800 ; retract
G1 Z1.0
G1 X{X0 + 100:g} Y{Y0 + 100:g}
G1 X{X0 + 100:g} Y{Y0 + 101:g} Z3 F20000
G91
G1 Z5
G90
M104 S0
M84
"""


def _over(move) -> float:
    """How far the move's fastest axis is over its limit (1: at it)."""
    return max(speed / LIMITS[axis] for axis, speed in move.axis_speeds().items())


def test_feed_rates_above_the_profile_are_clamped_as_marlin_limits_them() -> None:
    """Every move keeps its path and filament; a move whose feed takes an axis over its maximum
    speed runs at the feed that puts that axis at its maximum, the others as asked."""
    text = SLICER.splitlines()
    checked = check_plain_program(text, PROFILE, "slicer.gcode")
    before, after = read_gcode(SLICER).moves, read_gcode("\n".join(checked.lines)).moves
    assert len(before) == len(after)
    over = 0
    for b, a in zip(before, after):
        assert (a.start, a.end, a.e) == (b.start, b.end, b.e), a
        if _over(b) > 1 + 1e-9:
            over += 1
            assert _over(a) == pytest.approx(1.0, abs=1e-4), (b, a)   # at the limit, not below it
        else:
            assert a.feed == b.feed, (b, a)
    z_lift = next(a for a in after if a.line == 5)
    assert z_lift.feed == MO.max_z_speed * 60                         # G1 Z15.0 F6000 -> F2400
    assert over == 6                                                  # counted from the program above
    assert f"G1 Z15.0 F{MO.max_z_speed * 60:g}" in checked.commands
    [note] = checked.notes(PROFILE)
    assert note.startswith(f"{over} moves' feed rates clamped to the profile (E ≤ {MO.max_e_speed:g} mm/s, "
                           f"Z ≤ {MO.max_z_speed:g} mm/s)") and note.endswith("at line 5"), note


def test_a_program_within_the_limits_is_not_changed() -> None:
    lines = ["G28", "G90", "G1 Z2 F600", f"G1 X{X0 + 5} Y{Y0 + 5} F{MO.max_xy_speed * 60:g}",
             f"G1 X{X0 + 10} Y{Y0 + 5} E0.5 F{MO.print_speed * 60:g}"]
    checked = check_plain_program(lines, PROFILE, "fine.gcode")
    assert checked.lines == lines and checked.notes(PROFILE) == []
