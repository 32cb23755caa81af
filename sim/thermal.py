"""First-order heater model for the hotend and the bed.

Temperatures follow exact exponential solutions, so updating lazily (whenever
somebody looks) gives the same result as ticking, whatever the step size.
Time constants are in physical seconds; the caller converts wall time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Heater", "AMBIENT_C"]

AMBIENT_C = 25.0
_COOL_FACTOR = 2.0  # passive cooling is slower than driven heating


@dataclass
class Heater:
    """One heater: ``tau_s`` physical seconds time constant, targets up to ``max_c``."""

    name: str
    tau_s: float
    max_c: float
    temp: float = AMBIENT_C
    target: float = 0.0

    def reset(self) -> None:
        self.temp = AMBIENT_C
        self.target = 0.0

    def advance(self, dt_phys: float) -> None:
        """Let ``dt_phys`` physical seconds pass."""
        if dt_phys <= 0:
            return
        if self.target > self.temp:
            # Driven toward the target: the heater (and its regulator) win.
            self.temp = self.target + (self.temp - self.target) * math.exp(-dt_phys / self.tau_s)
        else:
            floor = max(self.target, AMBIENT_C)
            if self.temp > floor:
                cooled = AMBIENT_C + (self.temp - AMBIENT_C) * math.exp(
                    -dt_phys / (self.tau_s * _COOL_FACTOR))
                # A regulated heater holds its target instead of cooling past it.
                self.temp = max(cooled, floor) if self.target > AMBIENT_C else cooled

    @property
    def power(self) -> int:
        """PWM 0..127 as Marlin reports in ``@:``: full while far below, holding near."""
        if self.target <= 0:
            return 0
        hold = 0.5 * (self.target - AMBIENT_C) / max(1.0, self.max_c - AMBIENT_C)
        drive = (self.target - self.temp) / 10.0
        return int(max(0.0, min(1.0, hold + drive)) * 127)

    def reached(self, wait_cooling: bool) -> bool:
        """Marlin M109/M190 exit test: within 1 °C when heating (or either way with R)."""
        if self.target <= 0:
            # Cooling to "off": done when near ambient.
            return (not wait_cooling) or self.temp <= AMBIENT_C + 5.0
        if self.temp >= self.target - 1.0:
            return (not wait_cooling) or self.temp <= self.target + 1.0
        return False

    def time_to_reach(self) -> float:
        """Physical seconds until ``reached`` (heating) turns true; inf if never."""
        gap = self.target - self.temp
        if gap <= 1.0:
            return 0.0
        return self.tau_s * math.log(gap / 1.0) + 1e-6

    def time_to_cool(self, limit: float) -> float:
        """Physical seconds until passive cooling brings temp down to ``limit``."""
        if self.temp <= limit:
            return 0.0
        if limit <= AMBIENT_C:
            return math.inf
        return self.tau_s * _COOL_FACTOR * math.log((self.temp - AMBIENT_C) / (limit - AMBIENT_C)) + 1e-6
