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


def umbilic_split(kappa1: np.ndarray, kappa2: np.ndarray, anisotropy: np.ndarray, threshold: float,
                  flat_curvature: float) -> dict[str, float]:
    """The faces where k1 is not defined (anisotropy ≤ ``threshold``), by why (issue 34).

    |κ1| ≈ |κ2| is an umbilic only with the same sign (a sphere's point). With opposite signs (K < 0,
    H ≈ 0, a symmetric saddle) the curvature is not isotropic at all: its two principal directions
    bend by as much, one each way, so which one the ribbons follow is ambiguous. Faces whose
    |κ1| + |κ2| is below ``flat_curvature`` are flat (their signs are noise) and count as umbilic.

    Parameters
    ----------
    kappa1, kappa2 : (m,) signed principal curvatures, 1/mm; anisotropy : (m,) as the line field's;
    threshold : the umbilic tolerance; flat_curvature : κ below which a face is flat, 1/mm.

    Returns
    -------
    ``{"umbilic_pct", "ambiguous_pct"}``: the share of faces at or below the threshold (format 2's
    ``umbilic_pct``), and of those with opposite signs that are not flat, % of all faces.
    """
    k1, k2, a = (np.asarray(x, dtype=float) for x in (kappa1, kappa2, anisotropy))
    if not (k1.shape == k2.shape == a.shape and k1.ndim == 1):
        raise ValueError(f"kappa1, kappa2 and anisotropy must be 1-D of one length, got {k1.shape}, "
                         f"{k2.shape}, {a.shape}")
    low = a <= threshold
    ambiguous = low & (k1 * k2 < 0) & (np.abs(k1) + np.abs(k2) >= flat_curvature)
    n = max(len(a), 1)
    return {"umbilic_pct": float(100.0 * low.sum() / n), "ambiguous_pct": float(100.0 * ambiguous.sum() / n)}
