"""The byte window's governor: overflow told from noise by a trial with the safe window (issue 16)."""

from __future__ import annotations

import random

import pytest

from ribbond.printer.window import SAFE_WINDOW, Verdict, WindowGovernor


def stream(governor: WindowGovernor, lines: int, error: "callable", rng: random.Random) -> None:
    """Send ``lines`` lines at the governor's window, each failing when ``error(window, rng)``."""
    for _ in range(lines):
        offset = governor.window  # a full window: every line ends at its edge, as in steady state
        governor.line_sent(offset)
        if error(offset, rng):
            governor.line_error(offset)


def overflow(offset: int, rng: random.Random) -> bool:
    """A 64-byte board: lines beyond it are lost one time in ten, never within it."""
    return offset > 63 and rng.random() < 0.1


def noise(offset: int, rng: random.Random) -> bool:
    return rng.random() < 0.05


def test_overflow_shrinks_the_window_and_keeps_it() -> None:
    governor = WindowGovernor(127)
    stream(governor, 2000, overflow, random.Random(1))
    assert governor.verdict is Verdict.OVERFLOW
    assert governor.window == SAFE_WINDOW
    assert governor.advice is not None and "rx_buffer = 63" in governor.advice and "127" in governor.advice


def test_noise_leaves_the_window_as_configured() -> None:
    for seed in range(20):
        governor = WindowGovernor(127)
        stream(governor, 4000, noise, random.Random(seed))
        assert governor.verdict in (Verdict.NOISE, Verdict.TRIAL), seed
        assert governor.advice is None, "nothing to configure against noise"
        if governor.verdict is Verdict.NOISE:
            assert governor.window == 127


def test_a_noise_trial_ends_at_the_third_error_and_backs_off() -> None:
    governor = WindowGovernor(127)
    for _ in range(3):  # errors beyond the safe window
        governor.line_sent(127)
        governor.line_error(127)
    assert governor.verdict is Verdict.TRIAL and governor.window == SAFE_WINDOW
    for _ in range(3):  # errors with the small window too
        governor.line_sent(SAFE_WINDOW)
        governor.line_error(SAFE_WINDOW)
    assert governor.verdict is Verdict.NOISE and governor.window == 127
    for _ in range(3):  # more at once: no new trial before the cool-down has passed
        governor.line_sent(127)
        governor.line_error(127)
    assert governor.verdict is Verdict.NOISE and governor.window == 127


def test_errors_within_the_safe_window_start_no_trial() -> None:
    governor = WindowGovernor(127)
    for _ in range(10):
        governor.line_sent(40)
        governor.line_error(40)
    assert governor.verdict is Verdict.NONE and governor.window == 127


def test_a_window_already_safe_never_shrinks() -> None:
    governor = WindowGovernor(SAFE_WINDOW)
    stream(governor, 1000, lambda o, r: True, random.Random(0))
    assert governor.verdict is Verdict.NONE and governor.window == SAFE_WINDOW


def test_a_window_smaller_than_a_line_is_refused() -> None:
    with pytest.raises(ValueError, match="cannot hold one G-code line"):
        WindowGovernor(8)
