"""The last 30 minutes of temperatures (issue 22 item 6): sampled from the printer status the
service already polls for its events, kept in a bounded ring, served by ``GET
/printer/temperatures`` so the dashboard's chart starts full when the page opens.

A sample is ``{"t": unix s, "T": nozzle °C, "Tt": its target, "B": bed °C, "Bt": its target}`` (the
chart's own points); a heater the printer does not report is left out. At most one sample per
``interval_s``; samples older than ``span_s`` are dropped, so the ring holds at most
``span_s / interval_s`` of them whatever the polling rate.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from typing import Any

#: How far back the history reaches, s.
SPAN_S = 30 * 60.0
#: At most one sample per this many seconds.
INTERVAL_S = 1.0

#: The printer status's heater names and the sample's keys (actual, target).
_HEATERS = {"T": ("T", "Tt"), "B": ("B", "Bt")}


class TemperatureHistory:
    """A bounded ring of temperature samples (see the module's text)."""

    def __init__(self, span_s: float = SPAN_S, interval_s: float = INTERVAL_S,
                 clock: Callable[[], float] = time.time) -> None:
        if not (span_s > 0 and interval_s > 0):
            raise ValueError(f"span_s = {span_s}, interval_s = {interval_s}: both must be > 0")
        self.span_s, self.interval_s = span_s, interval_s
        self._clock = clock
        self._samples: deque[dict[str, float]] = deque(maxlen=math.ceil(span_s / interval_s) + 1)

    def sample(self, status: dict[str, Any]) -> bool:
        """Keep the temperatures of a printer status (``heaters``: ``{"T": {"current", "target"}}``);
        False when it has none or the last sample is younger than ``interval_s``."""
        now = self._clock()
        if self._samples and now - self._samples[-1]["t"] < self.interval_s:
            return False
        point: dict[str, float] = {}
        for name, (actual, target) in _HEATERS.items():
            heater = (status.get("heaters") or {}).get(name)
            if not isinstance(heater, dict) or heater.get("current") is None:
                continue
            point[actual] = float(heater["current"])
            point[target] = float(heater.get("target") or 0.0)
        if not point:
            return False
        self._samples.append({"t": now, **point})
        self._drop_old(now)
        return True

    def _drop_old(self, now: float) -> None:
        while self._samples and now - self._samples[0]["t"] > self.span_s:
            self._samples.popleft()

    def samples(self) -> list[dict[str, float]]:
        """The samples of the last ``span_s``, oldest first."""
        self._drop_old(self._clock())
        return list(self._samples)

    def as_json(self) -> dict[str, Any]:
        return {"span_s": self.span_s, "interval_s": self.interval_s, "samples": self.samples()}
