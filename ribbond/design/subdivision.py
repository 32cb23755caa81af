"""The hierarchy a mesh carries when it came from midpoint subdivision (1-to-4 splits).

Scans upsampled by their software and targets refined by our intake (``refine.py``, libigl's
``upsample_matrix``) are 1-to-4 splits of a coarser mesh, repeated: each coarse triangle (a, b, c)
becomes four, with one new vertex per coarse edge. Such a mesh holds its own coarse mesh exactly
(the coarse vertices are the first ones, kept where they were), and the flat map of the coarse mesh
carries over to the fine one by the subdivision relation itself: a new vertex at the middle of its
edge's two ends. The flattening's coarse start (``BoundedFlattener.coarse_start``) uses this in
place of a decimation.

The layout is libigl's (``igl.upsample``): coarse vertices first, the new edge vertices after them,
and the faces of coarse face k at rows 4k..4k+3 as (a, x, z), (b, y, x), (x, y, z), (y, c, z), with
x, y, z the new vertices on the edges ab, bc, ca. ``coarser_level`` accepts a mesh only when every
face and every new vertex fits that relation (one parent edge per new vertex, the same from both
faces that share it); anything else is not a subdivision, and the caller falls back.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: Row of the middle face (x, y, z) in each group of four: its k1 stands for the coarse face's.
MIDDLE = 2


def coarser_level(F: np.ndarray, n_vertices: int) -> tuple[np.ndarray, sp.csr_matrix] | None:
    """The coarse mesh whose 1-to-4 midpoint split is ``F``, or None if ``F`` is not one.

    Parameters
    ----------
    F : (m, 3) faces of the fine mesh, on vertices 0..n_vertices−1.

    Returns
    -------
    G : (m/4, 3) the coarse faces, on the fine mesh's first n_c vertices (n_c = G.max() + 1).
    S : (n_vertices, n_c) sparse prolongation: the identity on the coarse vertices, ½ and ½ on
        the two ends of its edge for each new vertex (fine = S @ coarse, exact for an affine map).
    """
    F = np.asarray(F, dtype=np.int64)
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or len(F) % 4:
        return None
    f0, f1, f2, f3 = F[0::4], F[1::4], F[2::4], F[3::4]
    a, b, c = f0[:, 0], f1[:, 0], f3[:, 1]
    x, y, z = f2[:, 0], f2[:, 1], f2[:, 2]
    # the four faces of each group are (a, x, z), (b, y, x), (x, y, z), (y, c, z)
    if not (np.array_equal(f0[:, 1], x) and np.array_equal(f0[:, 2], z) and np.array_equal(f1[:, 1], y)
            and np.array_equal(f1[:, 2], x) and np.array_equal(f3[:, 0], y) and np.array_equal(f3[:, 2], z)):
        return None
    G = np.column_stack([a, b, c])
    n_c = int(G.max()) + 1
    new = np.concatenate([x, y, z])
    if (new.min() < n_c or int(new.max()) >= n_vertices or np.any(G.min(axis=1) < 0)
            or np.any((a == b) | (b == c) | (c == a))):
        return None
    lo = np.concatenate([np.minimum(a, b), np.minimum(b, c), np.minimum(c, a)])
    hi = np.concatenate([np.maximum(a, b), np.maximum(b, c), np.maximum(c, a)])
    edge = lo * n_c + hi                                        # the parent edge, one integer each
    # every new vertex has one parent edge (the same from each face that names it), every coarse
    # edge one new vertex, and every vertex is either a coarse corner or a new one
    vertex, first, inverse = np.unique(new, return_index=True, return_inverse=True)
    parent = edge[first]
    if (not np.array_equal(parent[inverse], edge) or len(np.unique(parent)) != len(vertex)
            or len(vertex) != n_vertices - n_c or len(np.unique(G)) != n_c):
        return None
    rows = np.concatenate([np.arange(n_c), vertex, vertex])
    cols = np.concatenate([np.arange(n_c), parent // n_c, parent % n_c])
    vals = np.concatenate([np.ones(n_c), np.full(2 * len(vertex), 0.5)])
    return G, sp.csr_matrix((vals, (rows, cols)), shape=(n_vertices, n_c))


def subdivision_hierarchy(F: np.ndarray, n_vertices: int, max_faces: int
                          ) -> tuple[np.ndarray, sp.csr_matrix, np.ndarray] | None:
    """The coarsest useful level of ``F``'s subdivision hierarchy: descend 1-to-4 splits while the
    mesh has more than ``max_faces`` faces; None if it never gets to ``max_faces`` or fewer.

    Returns
    -------
    G : (k, 3) coarse faces (k ≤ max_faces) on the fine mesh's first G.max() + 1 vertices.
    P : (n_vertices, n_c) the prolongation, the product of each level's ``coarser_level`` S.
    child : (k,) a fine face inside each coarse face (the middle face's middle face, ...).
    """
    if max_faces < 1:
        raise ValueError(f"subdivision_hierarchy: max_faces = {max_faces}, must be >= 1")
    G, n = np.asarray(F, dtype=np.int64), n_vertices
    P = sp.identity(n_vertices, format="csr")
    child = np.arange(len(G))
    while len(G) > max_faces:
        level = coarser_level(G, n)
        if level is None:
            return None
        G, S = level
        P = (P @ S).tocsr()
        n = S.shape[1]
        child = child[4 * np.arange(len(G)) + MIDDLE]
    if len(G) == len(F):
        return None
    return G, P, child
