"""The profile's ``[adjust]`` table and the checker's ``printing`` mode (issue 36, item 10): what a
print in progress may be changed within, and that nothing else goes in beside a program. Limits come
from the profile; the refusals name the command and the limit."""

from __future__ import annotations

import pytest

from ribbond.gcode.checker import GcodeChecker, NotWhilePrinting
from ribbond.gcode.profiles import PrinterProfile, load_profile

PROFILE = load_profile("generic-marlin")
ADJ, T = PROFILE.adjust, PROFILE.temperatures


def _profile(**adjust: object) -> PrinterProfile:
    data = PROFILE.model_dump()
    data["adjust"] = {**data["adjust"], **adjust}
    return PrinterProfile.model_validate(data)


@pytest.mark.parametrize("adjust, words", [
    ({"speed_percent": (110.0, 150.0)}, "needs 0 < low ≤ 100 ≤ high"),
    ({"flow_percent": (80.0, 90.0)}, "needs 0 < low ≤ 100 ≤ high"),
    ({"speed_percent": (25.0, 400.0)}, "takes motion.travel_speed"),   # 150 mm/s × 4 > max_xy_speed 500
    ({"nozzle_min": T.nozzle + 1}, "adjust.nozzle_min"),
])
def test_the_profile_refuses_adjust_ranges_that_make_no_sense(adjust: dict, words: str) -> None:
    with pytest.raises(ValueError, match=words.replace("(", r"\(")):
        _profile(**adjust)


def test_the_shipped_top_speed_keeps_the_programs_speeds_within_the_maxima() -> None:
    for name in ("generic-marlin", "ultimaker2-tpu"):
        p = load_profile(name)
        top = p.adjust.speed_percent[1] / 100
        assert p.motion.travel_speed * top <= p.motion.max_xy_speed and p.motion.z_speed * top <= p.motion.max_z_speed


def _printing(commands: list[str]) -> list[str]:
    return GcodeChecker(PROFILE, source="console", printing=True).check(commands).commands


def test_beside_a_program_the_adjustments_at_their_limits_and_the_queries_pass() -> None:
    low, high = ADJ.speed_percent
    flow_low, flow_high = ADJ.flow_percent
    commands = [f"M220 S{low:g}", f"M220 S{high:g}", f"M221 S{flow_low:g}", f"M221 S{flow_high:g}",
                f"M104 S{ADJ.nozzle_min:g}", f"M104 S{T.nozzle_max:g}", "M140 S0", f"M140 S{T.bed_max:g}",
                "M105", "M114", "M220", "M221"]
    assert _printing(commands) == commands


WAIT = NotWhilePrinting        # refused only while a program prints


@pytest.mark.parametrize("command, kind, words", [
    ("G1 X100", WAIT, "G1 (it moves the head) is not accepted while a program prints"),
    ("G28", WAIT, "G28 (it moves the head)"),
    ("M109 S200", WAIT, "M109 is not accepted"),
    ("M400", WAIT, "M400 is not accepted"),
    ("M106 S255", WAIT, "M106 is not accepted"),
    (f"M220 S{ADJ.speed_percent[1] + 1:g}", ValueError, f"above {ADJ.speed_percent[1]:g} %"),
    (f"M220 S{ADJ.speed_percent[0] - 1:g}", ValueError, f"below {ADJ.speed_percent[0]:g} %"),
    (f"M221 S{ADJ.flow_percent[1] + 1:g}", ValueError, f"flow above {ADJ.flow_percent[1]:g} %"),
    (f"M104 S{ADJ.nozzle_min - 1:g}", WAIT, "adjust.nozzle_min"),
    (f"M104 S{T.nozzle_max + 1:g}", ValueError, "nozzle_max"),
    (f"M140 S{T.bed_max + 1:g}", ValueError, "bed_max"),
    ("M104 S220 B230", WAIT, "M104 B… is not accepted"),
    ("M220 S", ValueError, "needs a number"),
])
def test_beside_a_program_everything_else_is_refused_naming_it(command: str, kind: type, words: str) -> None:
    with pytest.raises(ValueError, match="console, line 2: ") as err:
        _printing(["M105", command])
    assert words in str(err.value), err.value
    assert (type(err.value) is NotWhilePrinting) == (kind is NotWhilePrinting), type(err.value)


def test_between_prints_the_ranges_hold_too_and_moves_are_checked_as_before() -> None:
    checker = GcodeChecker(PROFILE, source="program")
    assert checker.check(["G28", "G1 Z5 F600", f"M220 S{ADJ.speed_percent[1]:g}"]).commands[-1] == "M220 S150"
    with pytest.raises(ValueError, match="feed override above 150 %"):
        GcodeChecker(PROFILE, source="program").check(["M220 S151"])
