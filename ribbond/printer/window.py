"""The byte window: how many unacknowledged bytes the sender lets be in flight (issue 16).

The sender counts every unacknowledged byte as if it were still in the printer's receive buffer
(it is, while the firmware is blocked in a long command or waits for a planner block). A window
larger than the board's buffer loses bytes whenever the firmware stops reading: lines are cut in
two, merged with the next or dropped whole, and each loss is answered by a line-check error.
Nothing the printer says tells those errors from line noise.

The governor tells them apart by experiment. After a few line errors on lines sent with more than
``SAFE_WINDOW`` bytes in flight, it shrinks the window to ``SAFE_WINDOW`` for a trial long
enough to expect several (eight) errors at the rate seen before. If the rate falls to a quarter or
less, the losses were overflow: the window stays small and the verdict says what to configure. If
not, the errors are noise (which a smaller window does not cure): the window goes back, as soon as
the trial has seen more errors than overflow allows, and the next trial waits twice as long.
"""

from __future__ import annotations

import enum
import logging

log = logging.getLogger(__name__)

#: Bytes that fit a 64-byte receive buffer (Marlin keeps one slot of its ring buffer free).
SAFE_WINDOW = 63


class Verdict(enum.Enum):
    NONE = "none"
    TRIAL = "trial"
    NOISE = "noise"
    OVERFLOW = "overflow"


class WindowGovernor:
    """The sender's byte window, shrunk after errors that a smaller window cures.

    Parameters
    ----------
    configured : the window the sender was given (``Capabilities.rx_buffer_bytes``).
    suspect_errors : this many errors on lines sent beyond ``SAFE_WINDOW`` (since the start or the
        last trial) start a trial.
    trial_errors : the trial lasts long enough to expect this many errors at the earlier rate.
    overflow_ratio : how many times fewer errors the trial must see to prove overflow.
    """

    def __init__(self, configured: int, *, suspect_errors: int = 3, trial_errors: float = 8.0,
                 overflow_ratio: float = 4.0) -> None:
        if configured < 16:
            raise ValueError(f"window of {configured} bytes cannot hold one G-code line (>= 16)")
        self.configured = configured
        self.window = configured
        self.verdict = Verdict.NONE
        self._suspect_errors = suspect_errors
        self._trial_errors, self._overflow_ratio = trial_errors, overflow_ratio
        self._sent = 0                       # lines transmitted
        self._beyond_sent = 0                # ... with more than SAFE_WINDOW bytes in flight, since the last trial
        self._beyond_errors = 0              # errors on those
        self._trial_until = 0
        self._trial_sent = self._trial_errors_seen = 0
        self._quiet_until = 0                # no trial before this many lines were sent
        self._cooldown = 1000

    @property
    def can_shrink(self) -> bool:
        return self.configured > SAFE_WINDOW

    def line_sent(self, offset: int) -> None:
        """A line went out; ``offset``: unacknowledged bytes with it included."""
        self._sent += 1
        if self.verdict is Verdict.TRIAL:
            self._trial_sent += 1
            if self._sent >= self._trial_until:
                self._judge()
        elif offset > SAFE_WINDOW:
            self._beyond_sent += 1

    def line_error(self, offset: int | None) -> None:
        """The printer refused a line sent with ``offset`` bytes in flight (None: not known)."""
        if self.verdict is Verdict.TRIAL:
            self._trial_errors_seen += 1
            if self._trial_errors_seen > self._trial_errors / self._overflow_ratio:
                self._judge()  # more errors than overflow allows: noise, no need to wait for the end
            return
        if not self.can_shrink or self.verdict is Verdict.OVERFLOW or offset is None or offset <= SAFE_WINDOW:
            return
        self._beyond_errors += 1
        if self._beyond_errors >= self._suspect_errors and self._sent >= self._quiet_until:
            self._start_trial()

    def _start_trial(self) -> None:
        rate = self._beyond_errors / max(1, self._beyond_sent)
        # Sized on a low estimate of the rate (a Poisson lower bound of the count seen): a few
        # errors by chance early on must not make a trial so short that noise passes for overflow.
        low = max(0.5, self._beyond_errors - 1.3 * self._beyond_errors ** 0.5) / max(1, self._beyond_sent)
        lines = int(min(1500, max(50, self._trial_errors / low)))
        self.verdict = Verdict.TRIAL
        self.window = SAFE_WINDOW
        self._trial_until = self._sent + lines
        self._trial_sent = self._trial_errors_seen = 0
        self._rate_before = rate
        log.info("line errors beyond %d bytes in flight (%.1f %% of those lines): trying a %d-byte window "
                 "for %d lines", SAFE_WINDOW, 100 * rate, SAFE_WINDOW, lines)

    @property
    def advice(self) -> str | None:
        """What the owner should configure, once a trial proved overflow (else None)."""
        if self.verdict is not Verdict.OVERFLOW:
            return None
        return (f"the printer lost bytes of lines sent beyond {SAFE_WINDOW} bytes in flight: its receive "
                f"buffer is smaller than the configured {self.configured} bytes. The window stays at "
                f"{SAFE_WINDOW} bytes; set [serial] rx_buffer = {SAFE_WINDOW}")

    def _judge(self) -> None:
        rate = self._trial_errors_seen / max(1, self._trial_sent)
        self._beyond_sent = self._beyond_errors = 0
        # The trial was sized to expect trial_errors at the earlier rate: a quarter of them or fewer
        # is a rate cut by four or more.
        if self._trial_errors_seen <= self._trial_errors / self._overflow_ratio:
            self.verdict = Verdict.OVERFLOW
            log.warning("%s (error rate %.1f %% before, %.1f %% with the smaller window)", self.advice,
                        100 * self._rate_before, 100 * rate)
            return
        self.verdict = Verdict.NOISE
        self.window = self.configured
        self._quiet_until = self._sent + self._cooldown
        self._cooldown *= 2
        log.info("line errors at %.1f %% with a %d-byte window too: line noise, not overflow; the window "
                 "goes back to %d bytes", 100 * rate, SAFE_WINDOW, self.configured)
