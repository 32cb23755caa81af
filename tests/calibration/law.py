"""A known curvature law κ(τ, μ2) and measurements generated from it (the truth the fit must recover)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

#: The stitch front curls this much more than the back in the law.
BACK_RATIO = 1.5


def law(side: str, tau: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """κ1 (1/mm): rises with τ and saturates, falls with μ2; the back 1/1.5 of the front."""
    k = 0.08 * np.asarray(tau) / (np.asarray(tau) + 0.5) * np.sqrt(5.0 / (np.asarray(mu) + 1.0))
    return k if side == "front" else k / BACK_RATIO


def law_thickness(side: str, kappa: float, mu: float) -> float:
    """The τ at which the law gives ``kappa`` at ``mu`` (inverse, by bisection)."""
    return brentq(lambda t: float(law(side, np.array(t), np.array(mu))) - kappa, 1e-4, 50.0)


def measurement_rows(coupons: list[dict], noise: float, seed: int, failed: tuple[int, ...] = ()) -> tuple[str, dict[int, float]]:
    """``measurements.csv`` text: each coupon's arc over its length (chord and sagitta; the radius when it
    rolls beyond a half circle), κ from the law times (1 + noise · N(0, 1)); and the κ each row means."""
    rng = np.random.default_rng(seed)
    lines = ["coupon,chord_mm,sagitta_mm,radius_mm"]
    truth = {}
    for c in coupons:
        n = c["coupon"]
        if n in failed:
            lines.append(f"{n},,,")
            continue
        k = float(law(c["side"], c["thickness_mm"], c["spacing_mm"])) * (1 + noise * rng.standard_normal())
        truth[n] = k
        r = 1.0 / k
        theta = c["width_mm"] * k
        if theta < math.pi:
            chord, sag = 2 * r * math.sin(theta / 2), r * (1 - math.cos(theta / 2))
            lines.append(f"{n},{chord:.6f},{sag:.6f},")
        else:
            lines.append(f"{n},,,{r:.6f}")
    return "\n".join(lines) + "\n", truth
