"""How far the predicted surface is from the target, intrinsically as well as in space (issue 23).

The distance after registration (``compare``) says "close" for a sheet that rolls or folds into a
bowl's volume while staying nearly developable. These measures say what the surface is:

- ``total_gaussian_curvature``: ∫K dA, the sum of the angle defects 2π − Σθ at the interior vertices
  (Gauss–Bonnet's discrete form: it converges to the integral of K as the mesh is refined; the
  boundary's turning, which completes it to 2πχ, is left out);
- ``surface_area``: Σ face areas;
- ``reached``: the rule behind ``report.deployed.reached`` (``REACHED_*``);
- ``verdict``: the sentence a person reads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["total_gaussian_curvature", "angle_defects", "surface_area", "Agreement", "reached", "verdict"]

#: Reached: mean deviation at most this, % of the target's diagonal.
REACHED_MEAN_PCT = 2.0
#: Reached: |∫K predicted − ∫K target| at most this share of |∫K target| ...
REACHED_CURVATURE_SHARE = 0.25
#: ... or at most this absolute amount (nearly developable targets: ∫K near 0).
REACHED_CURVATURE_ABS = 0.1
#: Reached: predicted area / target area within this of 1.
REACHED_AREA = 0.1
#: The spread is wide (the sheet is floppy) when the mean deviation over the releases varies by
#: more than this, % of the diagonal, and by more than half the nominal figure.
WIDE_SPREAD_PCT = 1.0


def _angles(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m, 3) the corner angles of each face."""
    P = V[F]
    out = np.empty(F.shape)
    for c in range(3):                                    # three corners, vectorized over faces
        a = P[:, (c + 1) % 3] - P[:, c]
        b = P[:, (c + 2) % 3] - P[:, c]
        out[:, c] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    return out


def total_gaussian_curvature(V: np.ndarray, F: np.ndarray) -> float:
    """∫K dA of the surface V (n, 3), F (m, 3): Σ over interior vertices of 2π − Σθ (dimensionless)."""
    V = np.asarray(V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"V must be (n, 3) and F (m, 3), got {V.shape} and {F.shape}")
    return angle_defects(F, len(V), _angles(V, F))


def angle_defects(F: np.ndarray, n: int, corner: np.ndarray) -> float:
    """Σ over the interior vertices of 2π − Σ of their corner angles ``corner`` (m, 3): ∫K (dimensionless)."""
    total = np.bincount(F.ravel(), weights=corner.ravel(), minlength=n)
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    key = e[:, 0] * n + e[:, 1]
    uniq, count = np.unique(key, return_counts=True)
    boundary = np.zeros(n, dtype=bool)
    b = uniq[count == 1]
    boundary[b // n] = True
    boundary[b % n] = True
    used = np.zeros(n, dtype=bool)
    used[F.ravel()] = True
    interior = used & ~boundary
    return float((2.0 * np.pi - total[interior]).sum())


def surface_area(V: np.ndarray, F: np.ndarray) -> float:
    """Σ face areas of V (n, 3), F (m, 3)."""
    P = np.asarray(V, dtype=float)[np.asarray(F, dtype=np.int64)]
    return float(0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1).sum())


@dataclass(frozen=True)
class Agreement:
    """The prediction against the target.

    Attributes
    ----------
    mean_pct, max_pct : the nominal deviation, % of the target's diagonal.
    curvature_predicted, curvature_target : ∫K dA of each surface.
    area_ratio : predicted area / target area.
    spread_mean, spread_max : (lo, hi) of the mean and max deviation over the releases tried.
    """

    mean_pct: float
    max_pct: float
    curvature_predicted: float
    curvature_target: float
    area_ratio: float
    spread_mean: tuple[float, float]
    spread_max: tuple[float, float]

    @property
    def curvature_kept(self) -> float:
        """The share of the target's ∫K the prediction has (1 when |∫K target| is ~0)."""
        t = self.curvature_target
        return self.curvature_predicted / t if abs(t) > REACHED_CURVATURE_ABS else 1.0

    @property
    def curvature_ok(self) -> bool:
        gap = abs(self.curvature_predicted - self.curvature_target)
        return gap <= max(REACHED_CURVATURE_SHARE * abs(self.curvature_target), REACHED_CURVATURE_ABS)

    @property
    def wide(self) -> bool:
        lo, hi = self.spread_mean
        return hi - lo > max(WIDE_SPREAD_PCT, 0.5 * self.mean_pct)


def reached(a: Agreement) -> bool:
    """The layout takes the target's shape: mean deviation ≤ ``REACHED_MEAN_PCT`` % of the diagonal,
    ∫K within ``REACHED_CURVATURE_SHARE`` of the target's (or ``REACHED_CURVATURE_ABS`` absolute), the
    area within ``REACHED_AREA`` of the target's, over the nominal release and every other one tried
    (the spread's worst mean deviation counts)."""
    return (a.spread_mean[1] <= REACHED_MEAN_PCT and a.mean_pct <= REACHED_MEAN_PCT and a.curvature_ok
            and abs(a.area_ratio - 1.0) <= REACHED_AREA)


def verdict(a: Agreement) -> str:
    """The sentence a person reads about the prediction."""
    kt, kp = a.curvature_target, a.curvature_predicted
    shape = f"∫K {kp:+.2f} against the target's {kt:+.2f}"
    floppy = (f"; the sheet is floppy: released in other plausible ways it lands {a.spread_mean[0]:.1f}–"
              f"{a.spread_mean[1]:.1f} % from the target on average, so the shape will depend on handling"
              if a.wide else "")
    if reached(a):
        kept = f" ({100 * a.curvature_kept:.0f} % of it)" if abs(kt) > REACHED_CURVATURE_ABS else ""
        return (f"will take the target's shape: {a.mean_pct:.1f} % of the diagonal from it on average, "
                f"{shape}{kept}, area {100 * a.area_ratio:.0f} % of the target's" + floppy)
    why = []
    if not a.curvature_ok:
        if abs(kt) > REACHED_CURVATURE_ABS and abs(kp) < abs(kt):
            why.append(f"keeps {100 * max(a.curvature_kept, 0.0):.0f} % of the target's curvature ({shape})"
                       + (": it rolls or folds into the target's volume without taking its shape"
                          if a.mean_pct <= 2 * REACHED_MEAN_PCT else ""))
        else:
            why.append(f"its curvature is not the target's ({shape})")
    if a.mean_pct > REACHED_MEAN_PCT or a.spread_mean[1] > REACHED_MEAN_PCT:
        why.append(f"lands {a.mean_pct:.1f} % of the diagonal from the target on average "
                   f"({a.max_pct:.1f} % at most)")
    if abs(a.area_ratio - 1.0) > REACHED_AREA:
        why.append(f"its area is {100 * a.area_ratio:.0f} % of the target's")
    return "will NOT take the target's shape: " + "; ".join(why) + floppy
