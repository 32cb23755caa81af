"""The checker's refusals beside a running program, word for word (issue 36 item 10; issue 35, the
mutation run's survivors): each names the command, what is accepted instead and the profile's limit,
so the operator knows what to do. Limits come from the shipped profile ``generic-marlin``; the
checker's tolerance (1e-6) lets a value written at a bound pass."""

from __future__ import annotations

import pytest

from ribbond.gcode.checker import GcodeChecker, NotWhilePrinting
from ribbond.gcode.profiles import load_profile

PROFILE = load_profile("generic-marlin")
ADJ = PROFILE.adjust
ACCEPTED = "M104, M105, M114, M140, M220, M221"     # the checker's table, sorted


def refusal(command: str) -> ValueError:
    with pytest.raises(ValueError) as err:
        GcodeChecker(PROFILE, source="console", printing=True).check([command])
    return err.value


@pytest.mark.parametrize("code", ["G0 X5", "G1 X5", "G28"])
def test_a_move_is_refused_saying_it_moves_the_head(code: str) -> None:
    word = code.split()[0]
    assert str(refusal(code)) == (f"console, line 1: {word} (it moves the head) is not accepted while a program "
                                  f"prints; only {ACCEPTED} are (pause the job first for anything else)")


def test_another_command_is_refused_naming_what_is_accepted() -> None:
    assert str(refusal("M106 S255")) == ("console, line 1: M106 is not accepted while a program prints; only "
                                         f"{ACCEPTED} are (pause the job first for anything else)")


@pytest.mark.parametrize("command, message", [
    ("M221 X5", "M221 X… is not accepted while a program prints (only S, T)"),
    ("M105 S1", "M105 S… is not accepted while a program prints (only the bare command)"),
])
def test_a_word_the_adjustment_does_not_take_is_refused_naming_those_it_does(command: str, message: str) -> None:
    error = refusal(command)
    assert type(error) is NotWhilePrinting and str(error) == f"console, line 1: {message}"


@pytest.mark.parametrize("code", ["M220", "M221"])
def test_an_override_without_its_number_is_refused(code: str) -> None:
    error = refusal(f"{code} S")
    assert type(error) is ValueError and str(error) == f"console, line 1: {code} S needs a number (a percentage)"


def test_only_the_feed_override_above_its_range_is_said_to_outrun_the_limits() -> None:
    low, high = ADJ.speed_percent
    assert str(refusal(f"M220 S{high + 1:g}")) == (
        f"console, line 1: M220 S{high + 1:g} sets the feed override above {high:g} % (the profile's "
        f"adjust.speed_percent is {low:g}-{high:g} %), so moves would run faster than the profile's limits allow")
    low, high = ADJ.flow_percent
    assert str(refusal(f"M221 S{high + 1:g}")) == (
        f"console, line 1: M221 S{high + 1:g} sets the flow above {high:g} % (the profile's "
        f"adjust.flow_percent is {low:g}-{high:g} %)")


def test_a_nozzle_below_the_printing_minimum_is_refused_saying_why() -> None:
    low = ADJ.nozzle_min
    error = refusal(f"M104 S{low - 1:g}")
    assert type(error) is NotWhilePrinting
    assert str(error) == (f"console, line 1: nozzle {low - 1:g} °C while printing is below the profile's "
                          f"adjust.nozzle_min ({low:g} °C): the nozzle would stop extruding and the rest of the "
                          "program run dry (cancel or pause the job to cool it)")


def test_values_at_a_bound_within_the_tolerance_pass() -> None:
    commands = [f"M220 S{ADJ.speed_percent[0] - 1e-6:.6f}", f"M221 S{ADJ.flow_percent[0] - 1e-6:.6f}",
                f"M104 S{ADJ.nozzle_min - 1e-6:.6f}"]
    checked = GcodeChecker(PROFILE, source="console", printing=True).check(commands).commands
    assert checked == commands
