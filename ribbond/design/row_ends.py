"""Rows continued straight where the stripes turn away from the field (issue 34).

Where the number of rows changes (the torus patch's rows are fewer along its inner rim than along its
outer one), the stripe pattern joins two rows in a U-turn, usually at the outline, and at a saddle's
centre the rows turn through 90° at the diagonals. The layout trims such turns (``max_trim_angle``,
§6.2), and the fabric there was left bare: the torus patch's rows lost up to 10 mm at each end, the
along contraction there was 5 % short of Eq. 10's and the predicted patch lost its double curvature.

A dash whose row turns away after it (or before it) is continued straight along its own end
tangent, by Eq. 10's share f of the turned length it stands for (half of a turn shared with the next
dash of the row, all of a turn that ends the row), as far as the fabric that is kept (the inset
outline) and the other ribbons (half a row spacing μ2 away) allow. Extensions that meet each other
are cut where they meet.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.spatial import cKDTree

__all__ = ["turned_extensions", "extend_ends"]

#: Extensions are sampled, and their clearance checked, this often, mm.
STEP = 0.25
#: An end is extended only by at least this much, mm.
MIN_EXTENSION = 1.0


def turned_extensions(lo: np.ndarray, hi: np.ndarray, turned: np.ndarray, A: np.ndarray, B: np.ndarray,
                      row: np.ndarray, row_end: np.ndarray, row_start: np.ndarray, fraction: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """How far each dash [A, B] (arc length on its row ``row``) is to be continued at its start and end.

    Parameters
    ----------
    lo, hi : (q,) the row intervals (sorted, contiguous within a row); turned : (q,) those inside the
        outline that turn away from the field beyond the trim angle.
    A, B : (k,) the dashes, sorted; row : (k,) their row; row_start, row_end : (k,) their row's ends.
    fraction : (k,) Eq. 10's plastic share along at each dash, f = l_r / μ1.

    Returns
    -------
    (k,) extensions at A and at B, mm (0: none).
    """
    T = np.concatenate([[0.0], np.cumsum(np.where(turned, hi - lo, 0.0))])         # turned length up to lo[i]
    def upto(s: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(lo, s, side="right") - 1, 0, len(lo) - 1)
        return T[i] + np.where(turned[i], np.clip(s - lo[i], 0.0, hi[i] - lo[i]), 0.0)
    same_next = np.append(row[1:] == row[:-1], False)
    same_prev = np.insert(row[1:] == row[:-1], 0, False)
    after = upto(np.where(same_next, np.append(A[1:], 0.0), row_end)) - upto(B)
    before = upto(A) - upto(np.where(same_prev, np.insert(B[:-1], 0, 0.0), row_start))
    ext_hi = fraction * np.where(same_next, 0.5, 1.0) * np.maximum(after, 0.0)
    ext_lo = fraction * np.where(same_prev, 0.5, 1.0) * np.maximum(before, 0.0)
    return np.where(ext_lo >= MIN_EXTENSION, ext_lo, 0.0), np.where(ext_hi >= MIN_EXTENSION, ext_hi, 0.0)


def _end_rays(points: list[np.ndarray], at_end: bool) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) each polyline's end point and the unit tangent pointing out of it there (over ~2 mm)."""
    ends, tangents = [], []
    for p in points:                                   # one per ribbon (tens): their ends only
        q = p[::-1] if not at_end else p
        d = np.cumsum(np.r_[0.0, np.linalg.norm(np.diff(q[::-1], axis=0), axis=1)])
        k = min(int(np.searchsorted(d, 2.0)), len(q) - 1)
        t = q[-1] - q[-1 - k] if k > 0 else np.array([1.0, 0.0])
        ends.append(q[-1])
        tangents.append(t / max(np.linalg.norm(t), 1e-12))
    return np.array(ends).reshape(-1, 2), np.array(tangents).reshape(-1, 2)


def _clear(tree: cKDTree, owner_of: np.ndarray, P: np.ndarray, own: np.ndarray, clearance: np.ndarray
           ) -> np.ndarray:
    """(k,) True where point P[i] is at least clearance[i] from every sample of ``tree`` not owned by own[i]."""
    k = min(24, tree.n)
    d, idx = tree.query(P, k=k, distance_upper_bound=float(clearance.max()) if len(clearance) else 0.0,
                        workers=-1)
    d, idx = d.reshape(len(P), k), idx.reshape(len(P), k)
    hit = np.isfinite(d)
    other = hit & (owner_of[np.where(hit, idx, 0)] != own[:, None])
    return ~np.any(other & (d < clearance[:, None]), axis=1)


def _clear_length(start: np.ndarray, t: np.ndarray, length: np.ndarray, inset: shapely.Geometry,
                  tree: cKDTree, owner_of: np.ndarray, own: np.ndarray, clearance: np.ndarray) -> np.ndarray:
    """How far each ray (start + u t, u ≤ length) runs inside ``inset`` and at least ``clearance`` from
    the samples of ``tree`` that belong to other owners."""
    n = int(np.ceil(length.max() / STEP)) if len(length) else 0
    if n == 0:
        return np.zeros(len(start))
    u = STEP * np.arange(1, n + 1)
    P = start[:, None, :] + u[None, :, None] * t[:, None, :]                           # (k, n, 2)
    ok = shapely.contains_xy(inset, P[..., 0].ravel(), P[..., 1].ravel()).reshape(P.shape[:2])
    ok &= _clear(tree, owner_of, P.reshape(-1, 2), np.repeat(own, n), np.repeat(clearance, n)).reshape(P.shape[:2])
    ok &= u[None, :] <= length[:, None] + 1e-9
    first_bad = np.where(ok.all(axis=1), n, np.argmin(ok, axis=1))
    return np.where(first_bad > 0, np.minimum(u[np.maximum(first_bad - 1, 0)], length), 0.0)


def _samples(points: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Points every STEP or closer along each polyline, and the polyline of each."""
    lines = shapely.segmentize(shapely.linestrings(np.vstack(points), indices=np.repeat(
        np.arange(len(points)), [len(p) for p in points])), STEP)
    return shapely.get_coordinates(lines, return_index=True)


def extend_ends(points: list[np.ndarray], ext_lo: np.ndarray, ext_hi: np.ndarray, mu2: np.ndarray,
                inset: shapely.Geometry) -> list[np.ndarray]:
    """The ribbons ``points`` continued straight by ``ext_lo`` before their first point and ``ext_hi``
    after their last (mm), within ``inset`` and half a row spacing (``mu2`` (k,)) from other ribbons."""
    if not len(points) or not (np.any(ext_lo > 0) or np.any(ext_hi > 0)):
        return points
    xy, owner = _samples(points)
    tree = cKDTree(xy)
    clearance = 0.5 * np.asarray(mu2, dtype=float)
    rays = []
    for at_end, ext in ((False, ext_lo), (True, ext_hi)):
        start, t = _end_rays(points, at_end)
        sel = np.flatnonzero(ext > 0)
        L = _clear_length(start[sel], t[sel], ext[sel], inset, tree, owner, sel, clearance[sel])
        rays.append((sel, start[sel], t[sel], L))
    return _apply(points, _mutual(rays, clearance))


def _mutual(rays: list, clearance: np.ndarray) -> list:
    """Extensions cut where they come within clearance of another ribbon's extension."""
    pts, own, which = [], [], []
    for w, (sel, start, t, L) in enumerate(rays):
        for j in range(len(sel)):
            u = np.arange(STEP, L[j] + 1e-9, STEP)
            pts.append(start[j] + u[:, None] * t[j])
            own.append(np.full(len(u), sel[j]))
            which.append(np.full(len(u), w * 10**9 + j))
    if not pts:
        return rays
    P, O, W = np.vstack(pts), np.concatenate(own), np.concatenate(which)
    tree = cKDTree(P)
    pairs = tree.query_pairs(r=float(clearance.max()), output_type="ndarray")
    if len(pairs):
        d = np.linalg.norm(P[pairs[:, 0]] - P[pairs[:, 1]], axis=1)
        clash = (O[pairs[:, 0]] != O[pairs[:, 1]]) & (d < np.minimum(clearance[O[pairs[:, 0]]], clearance[O[pairs[:, 1]]]))
        for a in pairs[clash].ravel():                      # cut each clashing ray before its first clash
            w, j = divmod(int(W[a]), 10**9)
            sel, start, t, L = rays[w]
            L[j] = min(L[j], max(float(np.dot(P[a] - start[j], t[j])) - STEP, 0.0))
    return rays


def _apply(points: list[np.ndarray], rays: list) -> list[np.ndarray]:
    out = [p.copy() for p in points]
    (sel_lo, start_lo, t_lo, L_lo), (sel_hi, start_hi, t_hi, L_hi) = rays
    for j, i in enumerate(sel_lo):
        if L_lo[j] >= MIN_EXTENSION:
            out[i] = np.vstack([start_lo[j] + L_lo[j] * t_lo[j], out[i]])
    for j, i in enumerate(sel_hi):
        if L_hi[j] >= MIN_EXTENSION:
            out[i] = np.vstack([out[i], start_hi[j] + L_hi[j] * t_hi[j]])
    return out
