"""Refine a coarse target mesh to the resolution the design needs (issue 23, item 7).

Scans and exports often come with a few hundred to a few thousand faces. The engine's stages work
per face (one stretch, one direction per face), so on such meshes the ribbons follow a piecewise
constant field and turn at every coarse edge. Refinement gives them a smooth surface to follow.

Method: midpoint subdivision, each new vertex then lifted onto a smooth local fit of the coarse
surface (an interpolating scheme: the coarse vertices stay where they are).

1. At each coarse vertex i, a height function over its tangent plane, h_i(x, y) = d x + e y +
   a x² + b xy + c y², fitted by least squares to its two-ring (h_i(0, 0) = 0: it passes through
   the vertex). The frame's normal is the area-weighted vertex normal; the linear terms correct it.
2. ``levels`` rounds of midpoint subdivision (libigl's ``upsample_matrix``): every refined vertex
   p is an affine combination Σ w_k V_k of the corners of one coarse face (w: barycentric
   coordinates, 1 on itself for a coarse vertex).
3. The refined vertex is Σ w_k Q_k(p), Q_k(p) the point of vertex k's fit above p's tangential
   position in k's frame. A coarse vertex maps to itself (its weight is 1 and h_k(0) = 0); a point
   on a coarse edge depends only on that edge's two fits, so faces sharing the edge agree (no
   cracks), and the boundary's new vertices sit between consecutive boundary vertices: the
   boundary loop keeps its vertices, in order, with new ones between them.

Why this and not another scheme (measured in ``tests/design/test_refine.py`` and
``bench/accuracy.py``): Loop subdivision is approximating (it moves the file's vertices and shrinks
the surface by O(κ h²)); plain midpoint subdivision keeps the coarse facets, so its curvature is
concentrated on the coarse edges and the per-face estimate on the refined mesh is no better than on
the coarse one; a remesh would move the boundary. The local fits carry the coarse mesh's curvature
(to second order) to every new vertex.

A fit's lift is capped at ``MAX_LIFT`` × the distance to its vertex, so a spike or a fold in a
scan cannot throw new vertices far off the coarse surface; ``Refined.offset_pct`` reports the
largest distance of a refined vertex from the coarse surface (% of the bounding-box diagonal).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import igl
import numpy as np
import scipy.sparse as sp

from .intake import TargetMesh

#: The scheme, as the report names it.
METHOD = "midpoint subdivision onto local quadric fits"

#: A fit lifts a point by at most this share of its tangential distance to the fit's vertex: an arc
#: turning by 2 rad over a chord lifts its midpoint by 0.27 chord-halves, so smooth surfaces stay
#: below it and a wild fit (a spike, a fold) cannot throw a vertex far off the coarse surface.
MAX_LIFT = 0.5

#: Ridge on the curvature terms of a fit, relative to the normal equations' scale: a vertex whose
#: two-ring cannot determine a quadric (fewer than five neighbours in general position) gets a
#: plane instead of a singular solve.
_RIDGE = 1e-6


@dataclass(frozen=True)
class Refined:
    """A refined target.

    Attributes
    ----------
    V : (n', 3) vertex positions; the first n are the coarse mesh's, unchanged.
    F : (4^levels m, 3) faces, wound as the coarse faces they subdivide.
    levels : rounds of midpoint subdivision (0: the coarse mesh as given).
    offset_pct : largest distance of a refined vertex from the coarse surface, % of its
        bounding-box diagonal.
    """

    V: np.ndarray
    F: np.ndarray
    levels: int
    offset_pct: float
    method: str = METHOD


def levels_for(faces: int, refine_below: int, refine_to: int, max_faces: int) -> int:
    """The rounds of subdivision (each × 4 faces) for a mesh of ``faces`` faces: none when it has
    ``refine_below`` faces or more (``refine_below`` 0 turns refinement off), else the fewest that
    reach ``refine_to`` faces, without exceeding ``max_faces``."""
    if faces < 1 or refine_below < 0 or refine_to < 1 or max_faces < 1:
        raise ValueError(f"levels_for: faces = {faces}, refine_below = {refine_below}, refine_to = {refine_to}, "
                         f"max_faces = {max_faces}: need faces, refine_to, max_faces >= 1 and refine_below >= 0")
    if faces >= refine_below:
        return 0
    levels = 0
    while faces * 4 ** levels < refine_to and faces * 4 ** (levels + 1) <= max_faces:
        levels += 1
    return levels


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n, 3) unit area-weighted vertex normals of (V (n, 3), F (m, 3)); +z where a vertex has none."""
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])      # (m, 3), 2 × area × n
    N = np.zeros_like(V)
    for c in range(3):
        np.add.at(N, F[:, c], cross)
    length = np.linalg.norm(N, axis=1, keepdims=True)
    return np.where(length > 0, N / np.where(length > 0, length, 1.0), np.array([0.0, 0.0, 1.0]))


def _frames(N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (n, 3) each, orthogonal to the unit normals N (n, 3) and to each other."""
    helper = np.where((np.abs(N[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    t1 = np.cross(N, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(N, t1)


def _basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(k, 5) the fit's monomials x, y, x², xy, y² at (x, y) (k,) each."""
    return np.column_stack([x, y, x * x, x * y, y * y])


def _two_ring(F: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) pairs, j in the two-ring of i (i excluded): the rows and columns of A + A², A the
    vertex adjacency of F (m, 3)."""
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(np.float64)
    ring = (A + A @ A).tocoo()
    keep = ring.row != ring.col
    return ring.row[keep].astype(np.int64), ring.col[keep].astype(np.int64)


def fit_vertices(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The local height fits of (V (n, 3), F (m, 3)).

    Returns
    -------
    t1, t2, n : (n, 3) each, the frame of each vertex (n: its area-weighted normal).
    coef : (n, 5) the coefficients of h_i = d x + e y + a x² + b xy + c y² in that frame, fitted by
        least squares to the vertex's two-ring, lengths in the mesh's units.
    """
    N = vertex_normals(V, F)
    t1, t2 = _frames(N)
    i, j = _two_ring(F, len(V))
    d = V[j] - V[i]
    x, y, z = (np.einsum("kc,kc->k", d, t[i]) for t in (t1, t2, N))
    scale = np.sqrt(np.bincount(i, x * x + y * y, len(V)) / np.maximum(np.bincount(i, minlength=len(V)), 1))
    scale = np.where(scale > 0, scale, 1.0)                  # a lone vertex: any scale (its fit is 0)
    s = scale[i]
    B = _basis(x / s, y / s)                                 # scaled to the ring: well conditioned
    M = np.zeros((len(V), 5, 5))
    np.add.at(M, i, B[:, :, None] * B[:, None, :])
    rhs = np.zeros((len(V), 5))
    np.add.at(rhs, i, B * (z / s)[:, None])
    ridge = _RIDGE * (np.trace(M, axis1=1, axis2=2) + 1.0)
    M += ridge[:, None, None] * np.eye(5)
    c = np.linalg.solve(M, rhs[..., None])[..., 0]           # h/s as a function of (x/s, y/s)
    coef = c * np.column_stack([np.ones(len(V)), np.ones(len(V)), 1 / scale, 1 / scale, 1 / scale])
    return t1, t2, N, coef


def _subdivision(F: np.ndarray, n: int, levels: int) -> tuple[sp.coo_matrix, np.ndarray]:
    """The (n', n) matrix of ``levels`` midpoint subdivisions (rows: barycentric weights of each
    refined vertex on the coarse vertices) and the refined faces (4^levels m, 3)."""
    S = sp.identity(n, format="csc")
    faces = np.asarray(F, dtype=np.int64)
    for _ in range(levels):
        step, faces = igl.upsample_matrix(faces, S.shape[0])
        S = (step @ S).tocsc()
    return S.tocoo(), np.asarray(faces, dtype=np.int64)


def checked_input(caller: str, V: np.ndarray, F: np.ndarray, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """V as (n, 3) float64 and F as (m, 3) int64, or a ValueError naming ``caller`` and what is wrong."""
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or not np.isfinite(V).all():
        raise ValueError(f"{caller}: V must be an (n, 3) array of finite positions, got shape {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or F.min() < 0 or F.max() >= len(V):
        raise ValueError(f"{caller}: F must be a non-empty (m, 3) array of indices into V's {len(V)} "
                         f"vertices, got shape {F.shape}")
    if levels < 0:
        raise ValueError(f"{caller}: levels = {levels}: must be >= 0")
    return V, F


def refine(V: np.ndarray, F: np.ndarray, levels: int) -> Refined:
    """Refine (V (n, 3), F (m, 3)) by ``levels`` midpoint subdivisions onto the vertices' local fits.

    Returns
    -------
    Refined
        with 4^levels m faces; ``levels`` 0 returns the mesh as given.

    Raises
    ------
    ValueError
        when ``levels`` is negative, V is not (n, 3) finite or F not (m, 3) indices into V.
    """
    V, F = checked_input("refine", V, F, levels)
    if levels == 0:
        return Refined(V=V.copy(), F=F.copy(), levels=0, offset_pct=0.0)
    t1, t2, N, coef = fit_vertices(V, F)
    S, faces = _subdivision(F, len(V), levels)
    P = S @ V                                                # (n', 3) on the coarse facets
    r, k, w = S.row, S.col, S.data
    d = P[r] - V[k]
    x, y = np.einsum("ec,ec->e", d, t1[k]), np.einsum("ec,ec->e", d, t2[k])
    h = np.einsum("ec,ec->e", _basis(x, y), coef[k])
    cap = MAX_LIFT * np.hypot(x, y)                          # a wild fit stays near the facets
    h = np.clip(h, -cap, cap)
    Q = V[k] + x[:, None] * t1[k] + y[:, None] * t2[k] + h[:, None] * N[k]
    out = np.column_stack([np.bincount(r, w * Q[:, c], minlength=len(P)) for c in range(3)])
    out[: len(V)] = V                                        # exact, not merely to rounding
    return Refined(V=out, F=faces, levels=levels, offset_pct=offset_pct(out, V, F))


def offset_pct(points: np.ndarray, V: np.ndarray, F: np.ndarray) -> float:
    """Largest distance of ``points`` (k, 3) from the surface (V (n, 3), F (m, 3)), % of its
    bounding-box diagonal."""
    d2, _, _ = igl.point_mesh_squared_distance(np.ascontiguousarray(points), V, F)
    diagonal = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    return float(100.0 * np.sqrt(np.max(d2)) / diagonal) if diagonal > 0 else 0.0


#: The refinement schemes ``[solver] refine_method`` chooses from: "quadric" this module's (the
#: default), "smooth" ``refine_smooth``'s.
REFINE_METHODS = ("quadric", "smooth")


def refine_target(target: TargetMesh, refine_below: int, refine_to: int, max_faces: int,
                  method: str = "quadric") -> tuple[TargetMesh, Refined | None]:
    """The cleaned target refined when it has fewer than ``refine_below`` faces (see ``levels_for``)
    by ``method`` (one of ``REFINE_METHODS``), with its boundary loop recomputed; unchanged (and
    None) otherwise. ``source_faces``, the name and the digest stay the file's."""
    if method not in REFINE_METHODS:
        raise ValueError(f"refine_target: refine_method = {method!r}: must be one of {', '.join(REFINE_METHODS)}")
    levels = levels_for(len(target.F), refine_below, refine_to, max_faces)
    if levels == 0:
        return target, None
    from .refine_smooth import refine_smooth       # here: refine_smooth builds on this module's helpers
    fine = (refine_smooth if method == "smooth" else refine)(target.V, target.F, levels)
    loops = igl.boundary_loop_all(fine.F)
    if len(loops) != 1:       # subdivision keeps the topology: this would be a bug
        raise ValueError(f"refining {target.name} gave {len(loops)} boundary loops instead of one")
    return replace(target, V=fine.V, F=fine.F, boundary=np.asarray(loops[0], dtype=np.int64)), fine
