"""How far the printed plastic realizes the metric and curvature the flattening asked for (issue 34).

The flattening asks, per face, for a rest metric Ā = d dᵀ/σ1² + d⊥ d⊥ᵀ/σ2² (d the ribbon direction in
the flat) and a rest curvature |κ1| along d. The layout is meant to give them through Eq. 10 (§6.1):
a line whose plastic share is f keeps c = f + (1 − f)/s of its flat length when released. This module
measures what the ribbons as printed give, with the coverage the prediction uses
(``rest_forms.face_coverage``: both sides together, measuring lines that follow the rows over a
period, ± μ1 along and ± μ2 across), and compares it with what was asked:

- along, across: 100 (c_realized σ − 1) per face, with c_intended = 1/σ1 along and 1/σ2 across;
- the interior is the faces whose measuring window lies inside the flat outline (the centroid at least
  max(μ1, μ2) of Eq. 10 from the outline); the others are reported apart, as near the outline;
- the plastic area, printed (the rasterized ribbons) against Eq. 10's (Σ A f1 f2, fi = (s/σi − 1)/(s − 1));
- bare faces: no plastic within one μ2 of the centroid;
- the rest curvature: κ(τ, μ2) of the side's table at each nearby ribbon's τ and the realized μ2,
  against |κ1|, on faces where the table's range at that μ2 holds |κ1|; the share of ribbons whose τ
  is at the table's limits;
- ∫K of the intended metric (per-face lengths of the edges, averaged over an edge's two faces, angle
  defects at the interior vertices) against the target's, and ∫K of the realized one (the rest metric
  the prediction builds from the same coverage, ``rest_forms``; faces not measured take their nearest
  measured face's): where the realized metric loses curvature the prediction cannot keep it.

Pure: arrays and ribbons in, arrays and a report dict out; nothing here reads the target's shape but
its ∫K, which is the reference the intended metric is compared with.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ribbond.design.format import Ribbon
from ribbond.design.thickness import CurvatureTable, table_curvature

from .agreement import angle_defects, total_gaussian_curvature
from .rest_forms import Coverage, contraction, face_coverage, layout_raster, rest_forms

__all__ = ["Realization", "realization", "plastic_share", "metric_total_curvature", "realized_total_curvature"]


def plastic_share(sigma: np.ndarray, prestretch: float) -> np.ndarray:
    """Eq. 10's plastic share of a line, f = (s/σ − 1)/(s − 1): c = f + (1 − f)/s is then 1/σ."""
    s = float(prestretch)
    return np.clip((s / np.asarray(sigma, dtype=float) - 1.0) / (s - 1.0), 0.0, 1.0)


def _edge_lengths(uv: np.ndarray, F: np.ndarray, abar: np.ndarray) -> np.ndarray:
    """(m, 3) lengths of the edges opposite each corner under the per-face metric ``abar`` (m, 2, 2),
    each edge's squared length averaged over its faces (so neighbours agree)."""
    n = len(uv)
    E = np.stack([uv[F[:, 2]] - uv[F[:, 1]], uv[F[:, 0]] - uv[F[:, 2]], uv[F[:, 1]] - uv[F[:, 0]]], axis=1)
    l2 = np.einsum("mki,mij,mkj->mk", E, abar, E)
    a, b = np.roll(F, -1, axis=1), np.roll(F, -2, axis=1)             # the corners of the opposite edge
    key = np.minimum(a, b) * n + np.maximum(a, b)
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    mean = np.bincount(inv, weights=l2.ravel()) / np.bincount(inv)
    return np.sqrt(mean[inv].reshape(F.shape))


def metric_total_curvature(uv: np.ndarray, F: np.ndarray, abar: np.ndarray) -> float:
    """∫K of the metric ``abar`` (m, 2, 2) per face on the flat mesh uv (n, 2), F (m, 3): Σ over the
    interior vertices of 2π − Σθ, the angles from the edge lengths (law of cosines)."""
    L = _edge_lengths(np.asarray(uv, dtype=float), np.asarray(F, dtype=np.int64), abar)
    la, lb, lc = L[:, 0], L[:, 1], L[:, 2]
    ang = np.empty(L.shape)
    for c, (x, y, z) in enumerate(((la, lb, lc), (lb, lc, la), (lc, la, lb))):
        ang[:, c] = np.arccos(np.clip((y * y + z * z - x * x) / np.maximum(2 * y * z, 1e-300), -1.0, 1.0))
    return angle_defects(F, len(uv), ang)


def intended_metric(sigma: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(m, 2, 2) Ā = d dᵀ/σ1² + d⊥ d⊥ᵀ/σ2² in flat coordinates (the flattening's metric, pulled back)."""
    d = np.asarray(direction, dtype=float)
    n = np.column_stack([-d[:, 1], d[:, 0]])
    s = np.asarray(sigma, dtype=float)
    return (d[:, :, None] * d[:, None, :] / s[:, 0, None, None] ** 2
            + n[:, :, None] * n[:, None, :] / s[:, 1, None, None] ** 2)


@dataclass(frozen=True)
class Realization:
    """What the printed plastic realizes, per face (m,) and in total.

    Attributes
    ----------
    faces : (k,) the faces measured (all, or every j-th of a fine mesh); the per-face arrays are theirs.
    along, across : 100 (c_realized / c_intended − 1), %.
    interior : the faces whose measuring window lies inside the outline.
    bare : no plastic within one μ2.
    curvature : 100 (κ_rest / |κ1| − 1), % (nan where the table's range cannot give |κ1| or bare).
    plastic_printed, plastic_eq10 : plastic area, % of the flat area.
    clamped_pct : ribbons at the table's τ limits, %.
    k_target, k_intended, k_realized : ∫K of the target, of the intended metric and of the realized one.
    coverage : the measured coverage the figures come from.
    """

    faces: np.ndarray
    along: np.ndarray
    across: np.ndarray
    interior: np.ndarray
    bare: np.ndarray
    curvature: np.ndarray
    plastic_printed: float
    plastic_eq10: float
    clamped_pct: float
    k_target: float
    k_intended: float
    k_realized: float
    coverage: Coverage

    def report(self) -> dict:
        """``report.realization`` of design.json (format 4)."""
        def q(v: np.ndarray) -> dict | None:
            v = v[np.isfinite(v)]
            if len(v) == 0:
                return None
            p5, med, p95 = np.percentile(v, [5, 50, 95])
            return {"p5": round(float(p5), 2), "median": round(float(med), 2), "p95": round(float(p95), 2)}

        return {"along_pct": q(self.along[self.interior]), "across_pct": q(self.across[self.interior]),
                "along_pct_outline": q(self.along[~self.interior]),
                "across_pct_outline": q(self.across[~self.interior]),
                "plastic_pct": {"printed": round(self.plastic_printed, 2), "eq10": round(self.plastic_eq10, 2)},
                "bare_pct": round(100.0 * float(np.mean(self.bare)), 2),
                "curvature_pct": q(self.curvature), "clamped_pct": round(self.clamped_pct, 2),
                "total_gaussian_curvature": {"target": round(self.k_target, 4),
                                             "intended": round(self.k_intended, 4),
                                             "realized": round(self.k_realized, 4)}}


def _areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def realized_total_curvature(uv: np.ndarray, F: np.ndarray, faces: np.ndarray, cov: Coverage,
                             prestretch: float) -> float:
    """∫K of the rest metric the printed plastic realizes (``rest_forms`` of the coverage measured on
    ``faces`` (k,) of F (m, 3); every other face takes its nearest measured face's), on the flat uv (n, 2)."""
    abar = rest_forms(cov, prestretch).abar
    centroid = uv[F].mean(axis=1)
    if len(faces) < len(F):
        _, nearest = cKDTree(centroid[faces]).query(centroid, workers=-1)
        abar = abar[nearest]
    return metric_total_curvature(uv, F, abar)


def _rest_curvature_error(cov: Coverage, kappa1: np.ndarray, table: CurvatureTable) -> np.ndarray:
    """100 (κ_rest / |κ1| − 1) where the table at the realized μ2 can give |κ1| (nan elsewhere)."""
    k = np.abs(np.asarray(kappa1, dtype=float))
    side = np.where(kappa1 > 0, "front", "back")
    mu2 = np.where(np.isfinite(cov.mu2), cov.mu2, table.spacing[-1])
    lo = np.empty(len(k))
    hi = np.empty(len(k))
    for name in ("front", "back"):                                # two sides, vectorized over faces
        sel = side == name
        lo[sel] = table_curvature(table, name, np.full(sel.sum(), table.thickness[0]), mu2[sel])
        hi[sel] = table_curvature(table, name, np.full(sel.sum(), table.thickness[-1]), mu2[sel])
    ok = (~cov.bare) & (k >= lo) & (k <= hi) & (k > 0)
    signed = cov.kappa * np.sign(kappa1)                          # the wrong side reads as < −100 %
    return np.where(ok, 100.0 * (signed / np.where(ok, k, 1.0) - 1.0), np.nan)


def realization(uv: np.ndarray, F: np.ndarray, sigma: np.ndarray, direction: np.ndarray, kappa1: np.ndarray,
                ribbons: Sequence[Ribbon], *, prestretch: float, ribbon_width: float, ribbon_length: float,
                table: CurvatureTable, target_V: np.ndarray | None = None, max_faces: int = 4000) -> Realization:
    """Measure the metric and curvature the printed ribbons realize against the flattening's.

    Parameters
    ----------
    uv : (n, 2) the flat surface, mm; F : (m, 3) its faces (counter-clockwise).
    sigma : (m, 2) the flattening's σ1, σ2; direction : (m, 2) the ribbon direction per face (flat, unit);
    kappa1 : (m,) the target's signed curvature along it, 1/mm.
    ribbons : the ribbons as printed (both sides); table : the curvature table their τ came from.
    target_V : (n, 3) the target (for its ∫K); None: the intended metric's ∫K is compared with nothing.
    max_faces : the per-face figures are measured on at most this many faces (every k-th: the report's
        quantiles do not need every face of a fine mesh, and the coverage costs ~0.3 ms a face).
    """
    uv = np.asarray(uv, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    sigma = np.asarray(sigma, dtype=float)
    if sigma.shape != (len(F), 2):
        raise ValueError(f"sigma must have shape ({len(F)}, 2), got {sigma.shape}")
    raster = layout_raster(uv, F, ribbons, ribbon_width)
    faces = np.arange(0, len(F), max(1, -(-len(F) // max_faces)))        # evenly strided, deterministic
    area = _areas(uv, F)
    s = float(prestretch)
    eq10 = 100.0 * float(np.sum(area * plastic_share(sigma[:, 0], s) * plastic_share(sigma[:, 1], s)) / area.sum())
    k_int = metric_total_curvature(uv, F, intended_metric(sigma, direction))
    k_tgt = total_gaussian_curvature(target_V, F) if target_V is not None else float("nan")
    outline = shapely.union_all(shapely.polygons(uv[F]))
    F_all = F
    F, sigma, kappa1 = F[faces], sigma[faces], np.asarray(kappa1, dtype=float)[faces]
    cov = face_coverage(uv, F, ribbons, ribbon_width, table, raster=raster)
    k_real = realized_total_curvature(uv, F_all, faces, cov, s)
    along = 100.0 * (contraction(cov.f_along, s) * sigma[:, 0] - 1.0)
    across = 100.0 * (contraction(cov.f_across, s) * sigma[:, 1] - 1.0)
    f1, f2 = plastic_share(sigma[:, 0], s), plastic_share(sigma[:, 1], s)
    mu1 = ribbon_length / np.maximum(f1, 1e-9)
    mu2 = ribbon_width / np.maximum(f2, 1e-9)
    centroid = uv[F].mean(axis=1)
    edge_dist = shapely.distance(outline.boundary, shapely.points(centroid))
    interior = edge_dist >= np.maximum(mu1, mu2)
    near, _ = raster.tree.query(centroid, workers=-1) if len(raster.samples.xy) else (np.full(len(F), np.inf), None)
    bare = near - 0.5 * ribbon_width > mu2
    img = raster.image
    printed = 100.0 * float(img.covered.sum()) * img.pixel ** 2 / float(area.sum())
    tau = np.array([r.thickness for r in ribbons]) if ribbons else np.zeros(0)
    at_limit = (np.abs(tau - table.thickness[0]) < 1e-9) | (np.abs(tau - table.thickness[-1]) < 1e-9)
    clamped = 100.0 * float(at_limit.mean()) if len(tau) else 0.0
    return Realization(faces=faces, along=along, across=across, interior=interior, bare=bare,
                       curvature=_rest_curvature_error(cov, kappa1, table), plastic_printed=printed,
                       plastic_eq10=eq10, clamped_pct=clamped, k_target=k_tgt, k_intended=k_int,
                       k_realized=k_real, coverage=cov)
