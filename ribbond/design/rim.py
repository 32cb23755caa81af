"""A row along the outline where the rows run along it and the pattern left the rim bare (issue 34).

Where the ribbon direction runs along the outline, the stripe pattern's rows meet the rounded outline
as short chords: their dashes are clipped to pieces or dropped, and a band of bare fabric lies between
the last whole row and the cut. Bare fabric contracts by 1/s, so the outline there comes out shorter
than the flattening asks; and by Gauss–Bonnet (∫K = 2π − ∮k_g) the metric along the outline decides
the sheet's total curvature. On ``make demo``'s saddle the faces along such stretches of the outline
(3 % of them) held most of the curvature the printed metric lost.

``rim_ribbons`` lays a row on the outline shrunk by half a ribbon width (so its plastic reaches the
cut) wherever the direction field runs within ``RIM_ANGLE`` of the outline, no ribbon of at least
half a ribbon length lies within ``RIM_FREE`` μ2 (the next row is due at μ2) and the printed plastic
measurably falls short along the rows there (``RIM_SHORT``: where the pattern already carries the
outline, a rim row would add plastic the flattening did not ask for). Its dashes are sized by
Eq. 10 as the pattern's own: cells of about μ1, each holding the share f1 = l_r / μ1 of its length,
centred, at least ``min_ribbon_length``; split where κ1 changes sign (the side). The pattern's ribbons
that come within ``RIM_CLEAR`` ribbon widths of a rim dash are the chords it replaces and are dropped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely
from scipy.spatial import cKDTree

__all__ = ["RimRibbons", "rim_ribbons", "RIM_ANGLE", "RIM_FREE", "RIM_CLEAR", "RIM_SHORT"]

#: The rim gets a row where the direction field runs within this angle of the outline, degrees.
RIM_ANGLE = 30.0
#: ... and no ribbon of half a ribbon length or more lies within this share of μ2.
RIM_FREE = 0.6
#: Pattern ribbons within this many ribbon widths of a rim dash are dropped (the chords it replaces).
RIM_CLEAR = 2.0
#: The rim gets a row only where the plastic along the rows falls this many % short of Eq. 10's
#: contraction (a pattern whose rows already reach the cut, a cylinder's straight edges, reads ~0 %).
RIM_SHORT = 8.0
#: Samples along the rim, mm.
STEP = 0.25

Sampler = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class RimRibbons:
    """The rim's dashes and the pattern ribbons they replace.

    Attributes
    ----------
    points : (R,) polylines of (k, 2), mm; kappa1 : (R,) mean signed κ1 along each, 1/mm;
    spacing : (R, 2) Eq. 10's (μ1, μ2) at each dash's middle, mm; length : (R,) mm.
    replaced : (P,) bool, the pattern ribbons within ``RIM_CLEAR`` ribbon widths of a rim dash.
    """

    points: list[np.ndarray]
    kappa1: np.ndarray
    spacing: np.ndarray
    length: np.ndarray
    replaced: np.ndarray


def rim_ribbons(inset: shapely.Geometry, ribbons: list[np.ndarray], direction_at: Sampler, mu_at: Sampler,
                kappa1_at: Sampler, ribbon_length: float, ribbon_width: float, min_length: float,
                short_at: Sampler | None = None) -> RimRibbons:
    """The rim's rows (module docstring).

    Parameters
    ----------
    inset : the flat outline shrunk by half a ribbon width (where ribbon centerlines may run).
    ribbons : the pattern's ribbons, (k, 2) polylines, mm.
    direction_at, mu_at, kappa1_at : of points (p, 2): the unit ribbon direction (p, 2), Eq. 10's
        (μ1, μ2) (p, 2) and the signed κ1 (p,) there.
    ribbon_length, ribbon_width, min_length : l_r, w_r and the shortest ribbon kept, mm.
    short_at : of points (p, 2), True where the printed plastic falls short along the rows (the
        realized contraction along them more than ``RIM_SHORT`` % short of Eq. 10's): the rim gets a
        row only there. None: wherever the other conditions hold.
    """
    if not (ribbon_length > 0 and ribbon_width > 0 and min_length > 0):
        raise ValueError(f"ribbon_length, ribbon_width, min_length must be > 0, got {ribbon_length}, "
                         f"{ribbon_width}, {min_length}")
    lengths = np.array([_length(r) for r in ribbons])
    blocking = [_resample(np.asarray(r, dtype=float), 0.5) for r, n in zip(ribbons, lengths) if n >= 0.5 * ribbon_length]
    block = cKDTree(np.concatenate(blocking)) if blocking else None
    pieces = [piece for ring in _rings(inset)
              for piece in _free_runs(ring, block, direction_at, mu_at, kappa1_at, short_at)]
    dashes = [d for xy, k1, mu in pieces for d in _dashes(xy, k1, mu, ribbon_length, ribbon_width, min_length)]
    if block is not None:                   # a whole ribbon is never replaced: the dash gives way to it
        dashes = [(seg, k, m) for seg, k, m in
                  ((_longest(seg, block.query(seg, workers=-1)[0] >= RIM_CLEAR * ribbon_width), k, m)
                   for seg, k, m in dashes) if _length(seg) >= min_length]
    if not dashes:
        return RimRibbons(points=[], kappa1=np.zeros(0), spacing=np.zeros((0, 2)), length=np.zeros(0),
                          replaced=np.zeros(len(ribbons), dtype=bool))
    replaced = np.zeros(len(ribbons), dtype=bool)
    if ribbons:                             # every pattern ribbon's points against the dashes, at once
        points = np.concatenate([np.asarray(r, dtype=float) for r in ribbons])
        owner = np.repeat(np.arange(len(ribbons)), [len(r) for r in ribbons])
        near = cKDTree(np.concatenate([d[0] for d in dashes])).query(points, workers=-1)[0] < RIM_CLEAR * ribbon_width
        replaced[np.unique(owner[near])] = True
    return RimRibbons(points=[d[0] for d in dashes], kappa1=np.array([d[1] for d in dashes]),
                      spacing=np.array([d[2] for d in dashes]), length=np.array([_length(d[0]) for d in dashes]),
                      replaced=replaced)


def _rings(inset: shapely.Geometry) -> list[np.ndarray]:
    """The exterior ring of each part of the inset outline, resampled every ``STEP`` mm (open: the
    first point is not repeated)."""
    rings = []
    for part in shapely.get_parts(inset):
        ring = part.exterior
        n = max(int(np.ceil(ring.length / STEP)), 8)
        at = shapely.line_interpolate_point(ring, np.linspace(0.0, ring.length, n + 1)[:-1])
        rings.append(shapely.get_coordinates(at))
    return rings


def _free_runs(P: np.ndarray, block: cKDTree | None, direction_at: Sampler, mu_at: Sampler, kappa1_at: Sampler,
               short_at: Sampler | None):
    """The runs of the ring P (n, 2) where the field runs along it and no blocking ribbon is near,
    each cut where κ1 changes sign: (xy, κ1, (μ1, μ2)) per piece."""
    t = np.roll(P, -1, axis=0) - np.roll(P, 1, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    mu = mu_at(P)
    ok = np.abs(np.einsum("pc,pc->p", t, direction_at(P))) >= np.cos(np.radians(RIM_ANGLE))
    if block is not None:
        ok &= block.query(P, workers=-1)[0] > RIM_FREE * mu[:, 1]
    if short_at is not None:
        ok &= short_at(P)
    k1 = kappa1_at(P)
    out = []
    for a, b in _runs(ok):
        idx = np.arange(a, b) % len(P)
        cut = np.flatnonzero(np.sign(k1[idx][1:]) != np.sign(k1[idx][:-1])) + 1
        out.extend((P[i], k1[i], mu[i]) for i in np.split(idx, cut) if len(i) >= 2)
    return out


def _longest(seg: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The longest stretch of consecutive ``ok`` points of the polyline ``seg``."""
    if ok.all():
        return seg
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
    if len(edges) == 0:
        return seg[:0]
    a, b = max(zip(edges[::2], edges[1::2]), key=lambda ab: ab[1] - ab[0])
    return seg[a:b]


def _runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """[a, b) index runs of True on a closed ring (b may pass the end: indices wrap)."""
    n = len(ok)
    if ok.all():
        return [(0, n)]
    if not ok.any():
        return []
    start = int(np.flatnonzero(~ok)[0]) + 1                # begin after a False: no run wraps unseen
    rolled = np.roll(ok, -start).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rolled, [0]])))
    return [(start + int(a), start + int(b)) for a, b in zip(edges[::2], edges[1::2])]


def _dashes(xy: np.ndarray, k1: np.ndarray, mu: np.ndarray, ribbon_length: float, ribbon_width: float,
            min_length: float):
    """Cells of about μ1 along the run, each holding a centred dash of Eq. 10's share f1 = l_r / μ1
    of its length, a ribbon width short of the cell (dashes never fuse): (xy, mean κ1, (μ1, μ2))."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    n = max(int(round(s[-1] / float(np.mean(mu[:, 0])))), 1)
    edges = np.linspace(0.0, s[-1], n + 1)
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):                  # a few cells per run
        mid = 0.5 * (lo + hi)
        mu_mid = np.array([np.interp(mid, s, mu[:, 0]), np.interp(mid, s, mu[:, 1])])
        half = 0.5 * min(min(ribbon_length / mu_mid[0], 1.0) * (hi - lo), hi - lo - ribbon_width)
        if 2.0 * half < min_length:
            continue
        q = np.linspace(mid - half, mid + half, max(int(np.ceil(2.0 * half / STEP)) + 1, 2))
        seg = np.column_stack([np.interp(q, s, xy[:, 0]), np.interp(q, s, xy[:, 1])])
        out.append((seg, float(np.mean(np.interp(q, s, k1))), mu_mid))
    return out


def _length(xy) -> float:
    xy = np.asarray(xy, dtype=float)
    return float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))) if len(xy) > 1 else 0.0


def _resample(xy: np.ndarray, step: float) -> np.ndarray:
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
    q = np.linspace(0.0, s[-1], max(int(np.ceil(s[-1] / step)) + 1, 2))
    return np.column_stack([np.interp(q, s, xy[:, 0]), np.interp(q, s, xy[:, 1])])
