"""Short dashes where the rows leave the fabric bare (issue 34).

Where the line field is ambiguous (a saddle's |κ1| ≈ |κ2|) the rows of the stripe pattern close into
diamonds whose corners turn 90°: the ribbons there are trimmed or dropped, and spots of fabric a row
apart from any ribbon are left without plastic, so they contract by 1/s where the flattening asked
1/σ. Such a spot gets a dash along the field, sized by Eq. 10 on a local period: on a square lattice of
pitch P (the median μ2 of the flat domain), a dash of f1 P, f1 = l_r/μ1 the plastic share along
(so a row of them keeps 1/σ1 of its length, as the rows do), one ribbon width wide. A spot is bare when
its whole dash lies at least ``FILL_CLEARANCE`` μ2 from every ribbon (the rows are μ2 apart, so a
point of a complete layout is at most μ2/2 from one) and inside the outline shrunk by half the ribbon
width. On `make demo`'s saddle this adds three dashes (docs/benchmarks.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import shapely

from .remesh import locate

#: A dash fills a spot whose whole length lies at least this many μ2 from every ribbon.
FILL_CLEARANCE = 0.75


class Fill(NamedTuple):
    """The filling dashes: ``points`` one (2, 2) segment each, mm; ``kappa1`` (k,) signed curvature along
    the field at their centre, 1/mm; ``spacing`` (k, 2) (μ1, μ2) there; ``length`` (k,) mm."""

    points: list[np.ndarray]
    kappa1: np.ndarray
    spacing: np.ndarray
    length: np.ndarray


def fill_bare(uv: np.ndarray, F: np.ndarray, direction: np.ndarray, mu1: np.ndarray, mu2: np.ndarray,
              kappa1: np.ndarray, ribbons: list[np.ndarray], inset: shapely.Geometry, *, ribbon_length: float,
              ribbon_width: float, min_length: float, min_gap: float) -> Fill:
    """The dashes that fill the bare spots of a layout (see the module's docstring).

    Parameters
    ----------
    uv : (n, 2) the flat domain, mm; F : (m, 3) its faces; direction : (m, 2) the field per face (unit).
    mu1, mu2 : (n,) Eq. 10's spacing along and across at the vertices, mm; kappa1 : (n,) signed κ1, 1/mm.
    ribbons : the layout's ribbons, (k_r, 2) polylines, mm.
    inset : the outline shrunk by half the ribbon width (the dashes lie inside it).
    ribbon_length, ribbon_width : l_r and w_r, mm; min_length : the shortest dash, mm; min_gap : the
        shortest gap between two dashes' ends, mm.
    """
    if len(uv) == 0 or len(F) == 0 or not np.all(np.isfinite(mu2)) or np.any(mu2 <= 0):
        raise ValueError("fill_bare: the flat domain is empty or μ2 is not positive everywhere")
    P = float(np.median(mu2))
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    X, Y = np.meshgrid(np.arange(lo[0] + 0.5 * P, hi[0], P), np.arange(lo[1] + 0.5 * P, hi[1], P))
    centre = np.column_stack([X.ravel(), Y.ravel()])
    centre = centre[shapely.contains_xy(inset, centre[:, 0], centre[:, 1])]
    empty = Fill([], np.zeros(0), np.zeros((0, 2)), np.zeros(0))
    if len(centre) == 0 or not ribbons:
        return empty
    face, bary = locate(centre, uv, F)
    at = lambda v: np.einsum("kc,kc->k", bary, v[F[face]])                   # noqa: E731
    m1, m2, k1 = at(mu1), at(mu2), at(kappa1)
    # Eq. 10's share along on a period P, and a gap of at least min_gap to the next lattice dash
    length = np.clip(ribbon_length / m1 * P, min_length, max(P - min_gap, min_length))
    half = 0.5 * length[:, None] * direction[face]
    segments = shapely.linestrings(np.stack([centre - half, centre + half], axis=1))
    existing = shapely.multilinestrings([shapely.linestrings(r) for r in ribbons if len(r) >= 2])
    clear = np.maximum(FILL_CLEARANCE * m2, ribbon_width + min_gap)
    ok = (shapely.distance(segments, existing) >= clear) & shapely.contains(inset, segments) & (k1 != 0)
    if not ok.any():
        return empty
    ends = np.stack([centre - half, centre + half], axis=1)[ok]
    return Fill(points=list(ends), kappa1=k1[ok], spacing=np.column_stack([m1, m2])[ok], length=length[ok])
