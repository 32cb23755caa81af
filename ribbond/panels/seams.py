"""Seams between panels: where two panels meet, how long each edge is, where the stitch marks go.

A seam is a chain of target vertices on the boundary of two panels. Each panel's design has its own
flat layout, so the seam has a flat polyline on each panel (where the person cuts and sews) and a
deployed polyline on each panel's predicted shape. Stitch marks sit at matched fractions of each
side's deployed arc length: pinned mark to mark, the two edges ease into each other evenly even when
their deployed lengths differ a little (a tailor's easing).
"""

from __future__ import annotations

import string
from dataclasses import dataclass

import numpy as np

__all__ = ["SeamChain", "seam_chains", "polyline_length", "points_at_fractions", "outward_normals",
           "mark_fractions", "seam_label"]


@dataclass(frozen=True)
class SeamChain:
    """One seam on the target.

    Attributes
    ----------
    panels : (a, b) the two panels (0-based), a < b.
    vertices : (p,) target vertex indices along the seam, in the order of panel a's boundary loop.
    """

    panels: tuple[int, int]
    vertices: np.ndarray


def _edge_keys(loop: np.ndarray) -> np.ndarray:
    e = np.column_stack([loop, np.roll(loop, -1)])
    return np.sort(e, axis=1)


def _runs(flag: np.ndarray) -> list[np.ndarray]:
    """Cyclic runs of True in ``flag`` (n,), as index arrays in order."""
    n = len(flag)
    if flag.all():
        return [np.arange(n)]
    if not flag.any():
        return []
    start = int(np.flatnonzero(~flag)[0]) + 1               # start just after a False: no run wraps over it
    rolled = np.roll(flag, -start)
    idx = (np.arange(n) + start) % n
    edges = np.flatnonzero(np.diff(np.r_[0, rolled.astype(np.int8), 0]))
    return [idx[a:b] for a, b in zip(edges[::2], edges[1::2])]


def seam_chains(loops: list[np.ndarray]) -> list[SeamChain]:
    """The seams between panels given each panel's boundary loop in target vertex indices.

    Parameters
    ----------
    loops : per panel, its boundary loop (q_k,) as target vertex indices.

    Returns
    -------
    The seams, each a maximal run of boundary edges two panels share (a pair of panels meeting along
    two separate stretches has two seams), ordered by panel pair.
    """
    keys = [_edge_keys(loop) for loop in loops]
    chains = []
    for a in range(len(loops)):
        for b in range(a + 1, len(loops)):
            shared = (keys[a][:, None, 0] == keys[b][None, :, 0]) & (keys[a][:, None, 1] == keys[b][None, :, 1])
            flag = shared.any(axis=1)
            for run in _runs(flag):
                loop = loops[a]
                chains.append(SeamChain(panels=(a, b), vertices=np.r_[loop[run], loop[(run[-1] + 1) % len(loop)]]))
    return chains


def polyline_length(P: np.ndarray) -> float:
    """The length of a polyline (p, d)."""
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def points_at_fractions(P: np.ndarray, measure: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Points of the polyline P (p, d) where the arc length of another polyline ``measure`` (p, e)
    through the same parameter reaches the given fractions (k,) of its total (piecewise linear)."""
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(measure, axis=0), axis=1))]
    if s[-1] <= 0:
        raise ValueError("points_at_fractions: the measuring polyline has no length")
    t = np.clip(fractions, 0.0, 1.0) * s[-1]
    i = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(P) - 2)
    w = np.where(s[i + 1] > s[i], (t - s[i]) / np.maximum(s[i + 1] - s[i], 1e-300), 0.0)
    return P[i] * (1.0 - w)[:, None] + P[i + 1] * w[:, None]


def outward_normals(outline: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Unit normals (k, 2) pointing out of the counter-clockwise polygon ``outline`` (q, 2) at the
    nearest outline segment of each point (k, 2)."""
    a, b = outline, np.roll(outline, -1, axis=0)
    d = b - a
    t = np.clip(((points[:, None] - a[None]) * d[None]).sum(2) / np.maximum((d * d).sum(1), 1e-300)[None], 0, 1)
    near = a[None] + t[..., None] * d[None]
    seg = np.argmin(np.linalg.norm(points[:, None] - near, axis=2), axis=1)
    # average the two segments' normals where a point sits on a vertex: smoother on a jagged outline
    n = np.column_stack([d[:, 1], -d[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    smooth = n + np.roll(n, 1, axis=0) + np.roll(n, -1, axis=0)
    out = smooth[seg]
    return out / np.maximum(np.linalg.norm(out, axis=1), 1e-300)[:, None]


def mark_fractions(length: float, spacing: float) -> np.ndarray:
    """Where the stitch marks go on a seam of ``length`` mm, about ``spacing`` mm apart: fractions of its
    length strictly between its ends (the ends are the panels' corners, pinned as such; marks there would
    crowd the corner), at least one."""
    count = max(1, int(round(length / spacing)) - 1)
    return (np.arange(count) + 1.0) / (count + 1.0)


def seam_label(i: int) -> str:
    """A, B, …, Z, AA, AB, …: the i-th seam's (0-based) letters."""
    letters = string.ascii_uppercase
    return letters[i] if i < 26 else letters[i // 26 - 1] + letters[i % 26]
