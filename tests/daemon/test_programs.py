"""Programs as G-code: the time line (the programs' own estimate, ribbons, where printing starts)
and the line-by-line check of plain G-code against the printer profile. Expectations from the
geometry of the moves and from the profile's numbers."""

from __future__ import annotations

import pytest

from ribbond.gcode.profiles import load_profile
from ribbond.programs import check_program, program_timeline

PROFILE = load_profile("ultimaker2-tpu")
X0, Y0, X1, Y1 = PROFILE.frame.bounds


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
    (["G28", "G90", f"G0 X{X0 + 5} Y{Y0 + 5} F{PROFILE.motion.max_xy_speed * 60 + 1:g}"], 3, "max_xy_speed"),
    (["G28", "G90", f"G0 Z5 F{PROFILE.motion.max_z_speed * 60 + 1:g}"], 3, "max_z_speed"),
    (["M104 S" + f"{PROFILE.temperatures.nozzle_max + 1:g}"], 1, "nozzle_max"),
    (["M190 S" + f"{PROFILE.temperatures.bed_max + 1:g}"], 1, "bed_max"),
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
