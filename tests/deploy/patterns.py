"""Layouts built from their definition for the deploy tests: regular staggered ribbon patterns (§3)."""

from __future__ import annotations

import numpy as np

from ribbond.design.format import Ribbon


def staggered_pattern(size: tuple[float, float], mu1: float, mu2: float, length: float, thickness: float,
                      side: str = "front", origin: tuple[float, float] = (0.0, 0.0)) -> list[Ribbon]:
    """Ribbons along x over the rectangle origin + [0, X] × [0, Y]: rows every μ2 (the first at μ2/2),
    a ribbon of ``length`` every μ1 along each row, every other row shifted by μ1/2 (the paper's
    staggered pattern, §3 and §6.2), clipped to the rectangle."""
    X, Y = size
    kappa = 0.02 if side == "front" else -0.02
    out = []
    ys = np.arange(0.5 * mu2, Y, mu2)
    for j, y in enumerate(ys):
        shift = 0.5 * mu1 * (j % 2)
        for x0 in np.arange(-mu1 + shift, X + mu1, mu1):
            a, b = max(x0, 0.0), min(x0 + length, X)
            if b - a < 1.0:
                continue
            out.append(Ribbon(side=side, points=[(origin[0] + a, origin[1] + y), (origin[0] + b, origin[1] + y)],
                              thickness=thickness, kappa1=kappa, spacing=(mu1, mu2)))
    return out
