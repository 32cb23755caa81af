"""Deterministic fault injection on the serial link and in the firmware.

Each fault class draws from its own random stream derived from the seed, so a run
is reproducible and turning one fault on does not shift when another one fires.
"""

from __future__ import annotations

import random

from .config import FaultConfig

__all__ = ["FaultInjector", "UNSOLICITED_KINDS"]

# What an unsolicited line can be; "temperature" is formatted by the firmware.
UNSOLICITED_KINDS = ("busy", "temperature", "action", "settings")

_NL = 0x0A
_N = ord("N")


class FaultInjector:
    def __init__(self, config: FaultConfig, seed: int) -> None:
        self.config = config
        names = ("corrupt", "drop_ok", "spurious_resend", "unsolicited", "slow")
        self._rng = {name: random.Random(f"{seed}:{name}") for name in names}
        # Incoming line state for corruption, carried across reads.
        self._line_pos = 0
        self._pending = False
        self._accepted = 0
        self._fired: set[str] = set()

    def corrupt(self, data: bytes) -> tuple[bytes, int]:
        """Corrupt one byte of some incoming lines; return the data and how many lines."""
        rate = self.config.corrupt_rate
        if rate <= 0.0 or not data:
            return data, 0
        rng = self._rng["corrupt"]
        buf = bytearray(data)
        hits = 0
        pos = 0
        while pos < len(buf):
            nl = buf.find(b"\n", pos)
            end = len(buf) if nl < 0 else nl + 1
            if self._line_pos == 0:
                self._pending = rng.random() < rate
            if self._pending:
                # Never the leading N: the line-number check must still see a numbered line.
                lo = pos + 1 if self._line_pos == 0 and buf[pos] == _N else pos
                if lo < end:
                    i = rng.randrange(lo, end)
                    # A different printable byte (never \n or \r); replacing the newline
                    # itself merges two lines, which the checksum then catches.
                    new = rng.randrange(0x20, 0x7E)
                    if new >= buf[i]:
                        new += 1
                    buf[i] = new
                    self._pending = False
                    hits += 1
            self._line_pos = 0 if buf[end - 1] == _NL else self._line_pos + (end - pos)
            pos = end
        return bytes(buf), hits

    def reset_line_state(self) -> None:
        self._line_pos = 0
        self._pending = False

    def drop_ok(self) -> bool:
        r = self.config.drop_ok_rate
        return r > 0.0 and self._rng["drop_ok"].random() < r

    def spurious_resend(self) -> bool:
        r = self.config.spurious_resend_rate
        return r > 0.0 and self._rng["spurious_resend"].random() < r

    def unsolicited(self) -> str | None:
        """The kind of unsolicited line to slip in before the next output line, if any."""
        r = self.config.unsolicited_rate
        if r <= 0.0:
            return None
        rng = self._rng["unsolicited"]
        if rng.random() >= r:
            return None
        return rng.choice(UNSOLICITED_KINDS)

    def slow_delay(self) -> float:
        r = self.config.slow_rate
        if r > 0.0 and self._rng["slow"].random() < r:
            return self.config.slow_delay_s
        return 0.0

    def swallow_due(self) -> bool:
        """Whether the swallow_resent fault starts on the numbered line now arriving (once)."""
        after = self.config.swallow_resent_after_lines
        if after is None or "swallow" in self._fired or self._accepted < after:
            return False
        self._fired.add("swallow")
        return True

    def ignore_due(self) -> bool:
        """Whether the ignore_resent fault starts on the numbered line now arriving (once)."""
        after = self.config.ignore_resent_after_lines
        if after is None or "ignore" in self._fired or self._accepted < after:
            return False
        self._fired.add("ignore")
        return True

    def line_accepted(self) -> list[str]:
        """Count an accepted numbered line; return the one-shot triggers that fire now."""
        self._accepted += 1
        fired: list[str] = []
        for name, after in (("reset", self.config.reset_after_lines),
                            ("disconnect", self.config.disconnect_after_lines),
                            ("runaway", self.config.runaway_after_lines),
                            ("mintemp", self.config.mintemp_after_lines)):
            if after is not None and name not in self._fired and self._accepted >= after:
                self._fired.add(name)
                fired.append(name)
        return fired
