"""The smooth refinement of a coarse target (issue 34, item 6; ``[solver] refine_method = "smooth"``).

The default refinement is ``refine.py``'s (midpoint subdivision onto quadric fits, the file's vertices
kept); this one is chosen by the setting. ``refine.refine_target`` dispatches between them.

Scans and exports often come with a few hundred to a few thousand faces. The engine's stages work
per face (one stretch, one direction per face), so on such meshes the ribbons follow a piecewise
constant field and turn at every coarse edge. Refinement gives them a smooth surface to follow.

Method: local cubic fits of the coarse surface blended with Loop subdivision's smooth weights.

1. At each coarse vertex i, a height function over its tangent plane, h_i(x, y), a cubic (constant
   term included), fitted by weighted least squares to the vertex and its rings up to ``RING``.
   The frame's normal is the area-weighted vertex normal; the linear terms correct it. The
   constant term lets a fit miss its own vertex: a scan's noise is averaged, not interpolated.
2. ``levels`` rounds of Loop subdivision (Loop 1987, with the boundary rules of Hoppe et al. 1994
   and the boundary's corners kept), then its limit masks: every refined vertex gets a position
   p = Σ w_k V_k on Loop's limit surface, the weights w_k(p) ≥ 0 summing to 1 and varying smoothly
   over the surface (C² where the valence is 6, C¹ at other valences), each over the coarse
   two-ring of vertex k.
3. The refined vertex is Σ w_k Q_k(p), Q_k(p) the point of vertex k's fit above p's tangential
   position in k's frame. Every Q_k is a smooth function of p and the weights are smooth, so the
   surface is: where the fits agree (a smooth surface sampled without noise: the fits are right to
   third order) it is the fitted surface, and where they disagree (noise, a fit's error) the
   disagreement is spread smoothly instead of folding along the coarse edges.

The file's vertices move: each slides along the surface to its Loop limit position (by up to a
third of an edge on irregular triangulations; on a straight boundary it stays on it) and its height
is the blend of the fits, off the file's by their residual (the noise). The boundary keeps the
coarse boundary vertices in order with 2^levels − 1 new ones between neighbours; the corners
(``CORNER_DEG``) stay where they were, up to that residual.

Why this and not another scheme (per-face k1 of the refined surface against the exact one, on
``bench/accuracy.py --coarse``'s ~900-face meshes, measured on branch wt-refine2): the default
scheme, midpoint subdivision lifted onto two-ring quadric fits blended with the coarse faces'
barycentric weights, kept the file's vertices, but its weights have corners along the coarse edges,
so wherever two fits disagreed the surface creased there: on scan-like meshes with 0.02 mm noise
its k1 ran 1.5–9.8° median, 5–52° p95 off the exact one (the meshes as given: 0.2–1.9°, 0.7–5.9°;
this scheme: 0.15–0.65°, 0.6–3.1°), and it flipped faces. Loop subdivision alone is smooth but
follows the triangulation: its |κ1| was 4–10 % off (median), its k1 1.7–2.7°. Loop's weights over
the midpoint positions (the file's vertices kept) still crease: 2.6–2.9° median on the garment top.
Quadric fits over three rings gave 0.02–1.2° median, cubic fits over four rings 0.01–0.7°; the weak
ridge on the cubic terms (``CUBIC_RIDGE``) keeps the one-sided fits at the boundary from
extrapolating (|κ1| p95 12 % instead of 25 % on the noisy torus patch). The ribbons do not follow
all of it (docs/benchmarks.md, "Coarse targets refined at intake"): better on the noisy torus patch
and shoulder, worse on the garment top, where four rings (±20 mm) are too wide for its 8 mm bumps:
the fits' error is smooth at the coarse scale and the line field keeps it (``RING`` = 3 gives the
garment top's ribbons of the exactly sampled surface, but no longer averages a noisy scan's error
below the coarse mesh's own: the support should follow the noise).

A fit's lift is capped at ``MAX_LIFT`` × the distance to its vertex, so a spike or a fold in a
scan cannot throw new vertices far off the coarse surface; ``Refined.offset_pct`` reports the
largest distance of a refined vertex (the file's moved ones included) from the coarse surface (% of
the bounding-box diagonal).
"""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse as sp

from .refine import Refined, _frames, checked_input, offset_pct, vertex_normals
from .stripes import edge_topology

#: The scheme, as the report names it.
SMOOTH_METHOD = "Loop subdivision's limit weights blending local cubic fits (the file's vertices smoothed)"

#: A fit lifts a point by at most this share of its tangential distance to the fit's vertex: an arc
#: turning by 2 rad over a chord lifts its midpoint by 0.27 chord-halves, so smooth surfaces stay
#: below it and a wild fit (a spike, a fold) cannot throw a vertex far off the coarse surface.
MAX_LIFT = 0.5

#: Ridge on every term of a fit, relative to the normal equations' scale: a vertex whose rings
#: cannot determine a cubic (fewer than ten points in general position) gets a lower-order fit
#: instead of a singular solve.
_RIDGE = 1e-6

#: A boundary vertex where the boundary turns by more than this (degrees) is a corner: Loop's
#: boundary rule would round it off, so it stays (a grid's corners turn by 90°, a disk's by 360°/k).
CORNER_DEG = 30.0

#: The fits' data: the vertex and its rings up to this one, weighted exp(−(r/ρ)²), ρ the points'
#: RMS distance (about three rings' worth): a scan's noise averages out over some 60 points while
#: a smooth surface is still fitted to third order. Measured on ``bench/accuracy.py``'s coarse and
#: scan-like meshes against rings 2–4, widths 1–1.5, quadrics and cubics.
RING = 4

#: Ridge on a fit's cubic terms, relative to the mean eigenvalue of its normal equations: it
#: leaves the cubic terms of a vertex surrounded by data as they are and pulls those a one-sided
#: ring (the boundary's) cannot determine toward zero.
CUBIC_RIDGE = 0.01


#: The degree of each of ``_basis``'s monomials.
_DEGREE = np.array([0, 1, 1, 2, 2, 2, 3, 3, 3, 3])


def _basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(k, 10) the fit's monomials 1, x, y, x², xy, y², x³, x²y, xy², y³ at (x, y) (k,) each."""
    return np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y, x ** 3, x * x * y, x * y * y, y ** 3])


def _rings(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) pairs, j = i or j in the rings of i up to ``RING``: the pattern of (I + A)^RING, A
    the vertex adjacency of F (m, 3)."""
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(np.float64)
    step = A + sp.identity(n, format="csr")
    ring = step
    for _ in range(RING - 1):
        ring = ((ring @ step) > 0).astype(np.float64)
    ring = ring.tocoo()                                      # the vertex itself is data too
    return ring.row.astype(np.int64), ring.col.astype(np.int64)


def fit_cubics(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The local height fits of (V (n, 3), F (m, 3)).

    Returns
    -------
    t1, t2, n : (n, 3) each, the frame of each vertex (n: its area-weighted normal).
    coef : (n, 10) the coefficients of h_i, on ``_basis``'s monomials, in that frame, fitted by
        weighted least squares to the vertex and its rings up to ``RING``, lengths in the mesh's units.
    """
    N = vertex_normals(V, F)
    t1, t2 = _frames(N)
    i, j = _rings(F, len(V))
    d = V[j] - V[i]
    x, y, z = (np.einsum("kc,kc->k", d, t[i]) for t in (t1, t2, N))
    count = np.maximum(np.bincount(i, minlength=len(V)), 1)
    scale = np.sqrt(np.bincount(i, x * x + y * y, len(V)) / count)
    scale = np.where(scale > 0, scale, 1.0)                  # a lone vertex: any scale (its fit is 0)
    s = scale[i]
    B = _basis(x / s, y / s)                                 # scaled to the rings: well conditioned
    g = np.exp(-((x / s) ** 2 + (y / s) ** 2))               # the nearer points count more
    rows = sp.csr_matrix((g, (i, np.arange(len(i)))), shape=(len(V), len(i)))
    M = (rows @ (B[:, :, None] * B[:, None, :]).reshape(len(i), -1)).reshape(len(V), 10, 10)
    rhs = rows @ (B * (z / s)[:, None])
    trace = np.trace(M, axis1=1, axis2=2)
    M += (_RIDGE * (trace + 1.0))[:, None, None] * np.eye(10)
    M[:, 6:, 6:] += (CUBIC_RIDGE * trace / 10)[:, None, None] * np.eye(4)
    c = np.linalg.solve(M, rhs[..., None])[..., 0]           # h/s as a function of (x/s, y/s)
    return t1, t2, N, c * scale[:, None] ** (1 - _DEGREE)[None, :]


def _edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``stripes.edge_topology`` of F (m, 3) as Loop's rules read it: (e, 2) the edges' ends, the
    edge opposite each face corner (m, 3: side k joins corners k+1 and k+2), each edge's face count (e,)."""
    top = edge_topology(F)
    return top.edges, top.face_edges[:, [1, 2, 0]], top.faces_per_edge


def corners(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) bool: boundary vertices where the boundary turns by more than ``CORNER_DEG`` (the
    faces' angles there sum to less than 180° − CORNER_DEG); subdivision keeps them in place."""
    angles = igl.internal_angles(V, F)                       # (m, 3), radians at each corner
    total = np.bincount(F.ravel(), angles.ravel(), minlength=len(V))
    boundary = np.zeros(len(V), dtype=bool)
    for loop in igl.boundary_loop_all(F):
        boundary[np.asarray(loop, dtype=np.int64)] = True
    return boundary & (total < np.radians(180.0 - CORNER_DEG))


def _loop_rules(ends: np.ndarray, count: np.ndarray, n: int, corner: np.ndarray,
                limit: bool) -> sp.csr_matrix:
    """The (n, n) vertex rows of Loop subdivision (``limit``: its limit positions instead).

    Interior vertex of valence k: (1 − kβ) self + β each neighbour, β = (5/8 − (3/8 + cos(2π/k)/4)²)/k
    (Loop 1987); the limit mask puts χ = 1/(3/(8β) + k) on each neighbour. Boundary vertex: 3/4 self
    and 1/8 each boundary neighbour (limit 2/3, 1/6: the boundary is a cubic B-spline of its
    polygon); a corner stays.
    """
    on_boundary = count == 1
    boundary = np.zeros(n, dtype=bool)
    boundary[ends[on_boundary].ravel()] = True
    valence = np.bincount(ends.ravel(), minlength=n).astype(np.float64)
    k = np.maximum(valence, 3.0)
    beta = (5 / 8 - (3 / 8 + np.cos(2 * np.pi / k) / 4) ** 2) / k
    inner = 1.0 / (3 / (8 * beta) + k) if limit else beta
    edge_w = 1 / 6 if limit else 1 / 8
    i, j = np.concatenate([ends[:, 0], ends[:, 1]]), np.concatenate([ends[:, 1], ends[:, 0]])
    along = np.concatenate([on_boundary, on_boundary])
    w = np.where(boundary[i], np.where(along, edge_w, 0.0), inner[i])
    w = np.where(corner[i], 0.0, w)
    self_w = 1.0 - np.bincount(i, w, minlength=n)
    rows = np.concatenate([i, np.arange(n)])
    return sp.csr_matrix((np.concatenate([w, self_w]), (rows, np.concatenate([j, np.arange(n)]))), shape=(n, n))


def _loop_step(F: np.ndarray, n: int, corner: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
    """One round of Loop subdivision of F (m, 3) on n vertices: its (n + e, n) matrix (the old
    vertices first, then one per edge) and the 4m faces, each coarse face's four wound as it is."""
    ends, side, count = _edges(F)
    e = len(ends)
    # edge points: 3/8 each end and 1/8 each opposite corner inside, 1/2 each end on the boundary
    end_w = np.where(count == 2, 3 / 8, 1 / 2)
    rows = np.concatenate([np.arange(e), np.arange(e), side.ravel()])
    cols = np.concatenate([ends[:, 0], ends[:, 1], F.ravel()])
    vals = np.concatenate([end_w, end_w, np.where(count[side.ravel()] == 2, 1 / 8, 0.0)])
    E = sp.csr_matrix((vals, (rows, cols)), shape=(e, n))
    M = sp.vstack([_loop_rules(ends, count, n, corner, limit=False), E], format="csr")
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    bc, ca, ab = n + side[:, 0], n + side[:, 1], n + side[:, 2]
    fine = np.vstack([np.column_stack([a, ab, ca]), np.column_stack([b, bc, ab]),
                      np.column_stack([c, ca, bc]), np.column_stack([ab, bc, ca])])
    return M, fine


def subdivision(V: np.ndarray, F: np.ndarray, levels: int) -> tuple[sp.coo_matrix, np.ndarray]:
    """``levels`` rounds of Loop subdivision of (V (n, 3), F (m, 3)), boundary corners kept.

    Returns
    -------
    W : (n', n) the limit positions of the refined vertices as combinations of the coarse ones:
        each row a smooth partition of unity (≥ 0; the limit surface is C² where the valence is
        6, C¹ elsewhere), over the coarse vertices' two-ring.
    faces : (4^levels m, 3) the refined faces; the first n refined vertices are the coarse ones'.
    """
    n = len(V)
    corner = corners(V, F)
    W = sp.identity(n, format="csr")
    faces = np.asarray(F, dtype=np.int64)
    for _ in range(levels):
        step, faces = _loop_step(faces, W.shape[0], corner)
        W = (step @ W).tocsr()
        corner = np.concatenate([corner, np.zeros(step.shape[0] - len(corner), dtype=bool)])
    ends, _, count = _edges(faces)
    W = (_loop_rules(ends, count, W.shape[0], corner, limit=True) @ W).tocoo()
    W.sum_duplicates()
    return W, faces


def refine_smooth(V: np.ndarray, F: np.ndarray, levels: int) -> Refined:
    """Refine (V (n, 3), F (m, 3)) by ``levels`` rounds of subdivision onto the vertices' local fits,
    blended with Loop's limit weights (the module's docstring says how and why).

    Returns
    -------
    Refined
        with 4^levels m faces; ``levels`` 0 returns the mesh as given.

    Raises
    ------
    ValueError
        when ``levels`` is negative, V is not (n, 3) finite or F not (m, 3) indices into V.
    """
    V, F = checked_input("refine_smooth", V, F, levels)
    if levels == 0:
        return Refined(V=V.copy(), F=F.copy(), levels=0, offset_pct=0.0, method=SMOOTH_METHOD)
    t1, t2, N, coef = fit_cubics(V, F)
    W, faces = subdivision(V, F, levels)
    P = W @ V                                                # (n', 3) Loop's limit: smooth, shrunk a little
    r, k, w = W.row, W.col, W.data
    d = P[r] - V[k]
    x, y = np.einsum("ec,ec->e", d, t1[k]), np.einsum("ec,ec->e", d, t2[k])
    h = np.einsum("ec,ec->e", _basis(x, y), coef[k])
    cap = MAX_LIFT * np.hypot(x, y)                          # a wild fit stays near the facets
    h = coef[k, 0] + np.clip(h - coef[k, 0], -cap, cap)      # (the constant term: the noise's share)
    Q = V[k] + x[:, None] * t1[k] + y[:, None] * t2[k] + h[:, None] * N[k]
    out = np.column_stack([np.bincount(r, w * Q[:, c], minlength=len(P)) for c in range(3)])
    return Refined(V=out, F=faces, levels=levels, offset_pct=offset_pct(out, V, F), method=SMOOTH_METHOD)
