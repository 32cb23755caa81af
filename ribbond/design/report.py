"""The flattening's report: the columns of Table 1 of the paper, with the design format's names.

- ``k1_deviation_deg``: mean angle between k1 and the principal stretch direction of the final
  Jacobians (the one nearer k1);
- ``sigma{1,2}_max_dev``: the largest distance of a final principal stretch outside its bounds;
- ``sigma{1,2}_bad_pct``: the share of faces outside their bounds by more than 1e-3;
- ``avg_energy``: Eq. 3 divided by the total area.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .flatten import FlatteningResult

#: A face is "bad" for σi when its stretch lies outside the bounds by more than this (design-format.md).
BAD_TOLERANCE = 1e-3


def bounds_deviation(sigma: np.ndarray, lower: float, upper: float) -> np.ndarray:
    """(m,) how far each stretch lies outside [lower, upper] (0 inside)."""
    return np.maximum(np.maximum(lower - sigma, sigma - upper), 0.0)


def flattening_report(flat: FlatteningResult, area: np.ndarray,
                      bounds: tuple[tuple[float, float], tuple[float, float]],
                      timings: dict[str, float], total_time: float) -> dict[str, Any]:
    """The ``report`` fields of ``design.json`` for a flattening.

    Parameters
    ----------
    flat : the flattening; area : (m,) target face areas; bounds : the stretch bounds;
    timings : seconds per stage; total_time : seconds for the whole design.
    """
    dev1 = bounds_deviation(flat.sigma[:, 0], *bounds[0])
    dev2 = bounds_deviation(flat.sigma[:, 1], *bounds[1])
    per_iteration = flat.time_iterations_s / max(flat.iterations, 1)
    return {
        "faces": int(len(area)),
        "time_s": float(total_time),
        "iterations": int(flat.iterations),
        "k1_deviation_deg": float(np.degrees(flat.deviation.mean())),
        "sigma1_max_dev": float(dev1.max()),
        "sigma2_max_dev": float(dev2.max()),
        "sigma1_bad_pct": float(100.0 * np.mean(dev1 > BAD_TOLERANCE)),
        "sigma2_bad_pct": float(100.0 * np.mean(dev2 > BAD_TOLERANCE)),
        "avg_energy": float(flat.energy / area.sum()),
        "timings_s": {k: float(v) for k, v in timings.items()},
        "converged": bool(flat.converged),
        "time_per_iteration_s": float(per_iteration),
    }
