"""Cutting a target into panels: a spectral partition of its faces with seams where they cost least.

The paper's way past one sheet (§7): "introduce cuts in the parameterization, and stitch the fabric
along those cuts". A panel is a set of faces; a seam is the shared boundary of two panels. Seams
should be short (less to sew, less boundary where the flattening is free), run along the ribbon
direction k1 rather than across it (a seam across k1 ends every ribbon it meets), and avoid highly
curved regions. So each interior edge between faces f and g costs

    w_fg = ℓ_fg · (1 + a · sin² θ_fg) · (1 + |κ|_fg / mean |κ|)

with ℓ its length, θ the angle between the edge and k1 (averaged over f and g), a the curvature
anisotropy (0 at umbilics, where no direction is preferred) and |κ| the larger principal curvature.
A partition that cuts little weight relative to the panels' areas is a normalized cut; its relaxation
is the low eigenvectors of L x = λ M x with L the weighted Laplacian of the face graph and M the face
areas (Shi & Malik 2000). The k panels are k-means clusters of the first k − 1 nontrivial
eigenvectors (on a disk-like surface they are sectors: gores, as a tailor cuts a bowl), then cleaned:
each panel one connected piece, a topological disk.

Pure functions over arrays; the search for how many panels are needed (each must flatten within the
stretch bounds and fit the frame) is ``ribbond.panels.project``'s.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.cluster.vq import kmeans2
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import eigsh

__all__ = ["bisect", "longest_axis", "interior_edges", "seam_weights", "spectral_embedding", "partition", "panel_submesh",
           "boundary_loops", "cut_weight"]


def interior_edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The interior edges of a manifold triangle mesh.

    Parameters
    ----------
    F : (m, 3) faces.

    Returns
    -------
    pairs : (e, 2) the two faces that share each interior edge; verts : (e, 2) its two vertices.
    """
    F = np.asarray(F, dtype=np.int64)
    half = np.stack([F, np.roll(F, -1, axis=1)], axis=2).reshape(-1, 2)      # (3m, 2) directed edges
    key = np.sort(half, axis=1)
    face = np.repeat(np.arange(len(F)), 3)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, face = key[order], face[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    first = np.flatnonzero(same)
    return np.column_stack([face[first], face[first + 1]]), key[first]


def seam_weights(V: np.ndarray, verts: np.ndarray, pairs: np.ndarray, direction: np.ndarray,
                 anisotropy: np.ndarray, kappa_max: np.ndarray) -> np.ndarray:
    """The cost of cutting each interior edge (the module's w_fg).

    Parameters
    ----------
    V : (n, 3) vertices; verts : (e, 2) each edge's vertices; pairs : (e, 2) its two faces.
    direction : (m, 3) unit k1 per face (a line: its sign does not matter).
    anisotropy : (m,) in [0, 1]; kappa_max : (m,) the larger |principal curvature|, 1/mm.

    Returns
    -------
    (e,) positive weights, mm.
    """
    edge = V[verts[:, 1]] - V[verts[:, 0]]
    length = np.linalg.norm(edge, axis=1)
    t = edge / np.maximum(length, 1e-300)[:, None]
    cos2 = 0.5 * ((t * direction[pairs[:, 0]]).sum(1) ** 2 + (t * direction[pairs[:, 1]]).sum(1) ** 2)
    across = anisotropy[pairs].mean(axis=1) * (1.0 - cos2)
    kappa = np.abs(kappa_max)[pairs].mean(axis=1)
    curved = kappa / max(float(np.abs(kappa_max).mean()), 1e-300)
    return length * (1.0 + across) * (1.0 + curved)


def _face_laplacian(pairs: np.ndarray, weights: np.ndarray, m: int) -> sp.csr_matrix:
    W = sp.coo_matrix((np.concatenate([weights, weights]), (np.concatenate([pairs[:, 0], pairs[:, 1]]),
                                                          np.concatenate([pairs[:, 1], pairs[:, 0]]))),
                      shape=(m, m)).tocsr()
    return (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsc()


def spectral_embedding(pairs: np.ndarray, weights: np.ndarray, area: np.ndarray, dims: int) -> np.ndarray:
    """The first ``dims`` nontrivial eigenvectors of L x = λ M x on the face graph.

    Parameters
    ----------
    pairs : (e, 2) adjacent faces; weights : (e,) their edge weights; area : (m,) face areas (M).
    dims : how many eigenvectors (≥ 1).

    Returns
    -------
    (m, dims) the eigenvectors, M-orthonormal, in increasing order of λ.
    """
    m = len(area)
    if dims < 1 or dims + 2 > m:
        raise ValueError(f"spectral_embedding: dims must be in 1..{m - 2}, got {dims}")
    L = _face_laplacian(pairs, weights, m)
    M = sp.diags(area).tocsc()
    scale = float(weights.sum() / area.sum())          # λ's order of magnitude: 1 / length²
    vals, vecs = eigsh(L, k=dims + 1, M=M, sigma=-1e-3 * scale, which="LM")
    order = np.argsort(vals)
    return vecs[:, order[1:dims + 1]]


def cut_weight(labels: np.ndarray, pairs: np.ndarray, weights: np.ndarray) -> float:
    """The total weight of the edges between faces of different panels."""
    return float(weights[labels[pairs[:, 0]] != labels[pairs[:, 1]]].sum())


def _main_pieces(piece_label: np.ndarray, piece_area: np.ndarray) -> np.ndarray:
    """(n,) True for the largest piece of each panel."""
    order = np.lexsort((piece_area, piece_label))
    last = np.r_[piece_label[order][1:] != piece_label[order][:-1], True]
    main = np.zeros(len(piece_label), dtype=bool)
    main[order[last]] = True
    return main


def _merge_fragments(labels: np.ndarray, pairs: np.ndarray, weights: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Each panel one connected piece: a fragment apart from its panel's largest piece joins the panel
    it shares the most boundary weight with. Repeated until no fragment is left."""
    m, k = len(labels), int(labels.max()) + 1
    for _ in range(64):
        same = labels[pairs[:, 0]] == labels[pairs[:, 1]]
        G = sp.coo_matrix((np.ones(int(same.sum())), (pairs[same, 0], pairs[same, 1])), shape=(m, m))
        n, comp = connected_components(G, directed=False)
        piece_label = np.zeros(n, dtype=np.int64)
        piece_label[comp] = labels
        fragment = ~_main_pieces(piece_label, np.bincount(comp, weights=area, minlength=n))
        if not fragment.any():
            return labels
        # the weight each piece shares with each panel across its boundary (both directions of an edge)
        a, b = np.concatenate([pairs[~same, 0], pairs[~same, 1]]), np.concatenate([pairs[~same, 1], pairs[~same, 0]])
        shared = sp.coo_matrix((np.concatenate([weights[~same]] * 2), (comp[a], labels[b])), shape=(n, k)).toarray()
        joins = np.where(fragment & (shared.max(axis=1) > 0), shared.argmax(axis=1), piece_label)
        labels = joins[comp]
    raise ValueError("the panels' fragments did not settle in 64 passes")


def _smooth(labels: np.ndarray, pairs: np.ndarray, weights: np.ndarray, passes: int = 3) -> np.ndarray:
    """A face whose edges mostly border another panel joins it: straighter seams, fewer teeth."""
    m, k = len(labels), labels.max() + 1
    A = sp.coo_matrix((np.concatenate([weights, weights]), (np.concatenate([pairs[:, 0], pairs[:, 1]]),
                                                          np.concatenate([pairs[:, 1], pairs[:, 0]]))),
                      shape=(m, m)).tocsr()
    for _ in range(passes):
        onehot = sp.csr_matrix((np.ones(m), (np.arange(m), labels)), shape=(m, k))
        votes = (A @ onehot).toarray()
        own = votes[np.arange(m), labels]
        best = votes.argmax(axis=1)
        switch = votes[np.arange(m), best] > 2.0 * own
        if not switch.any():
            break
        labels = np.where(switch, best, labels)
    return labels


def partition(embedding: np.ndarray, k: int, pairs: np.ndarray, weights: np.ndarray, area: np.ndarray,
              restarts: int = 8) -> np.ndarray:
    """k panels: k-means of the spectral embedding (the lowest cut of ``restarts`` seeded runs), each
    panel then one connected piece with smoothed seams.

    Parameters
    ----------
    embedding : (m, d) the faces' spectral coordinates; k : panels (≥ 1).
    pairs, weights : the face graph (``interior_edges``, ``seam_weights``); area : (m,) face areas.

    Returns
    -------
    (m,) panel index of each face in 0..k−1, panels numbered by decreasing area.
    """
    m = len(area)
    if k < 1 or k > m:
        raise ValueError(f"partition: k must be in 1..{m}, got {k}")
    if k == 1:
        return np.zeros(m, dtype=np.int64)
    X = embedding / np.maximum(embedding.std(axis=0), 1e-300)
    best, best_cut = None, np.inf
    for seed in range(restarts):
        _, labels = kmeans2(X, k, minit="++", seed=seed)
        if len(np.unique(labels)) < k:
            continue
        labels = _merge_fragments(_smooth(labels.astype(np.int64), pairs, weights), pairs, weights, area)
        if len(np.unique(labels)) < k:
            continue
        cut = cut_weight(labels, pairs, weights)
        if cut < best_cut:
            best, best_cut = labels, cut
    if best is None:
        raise ValueError(f"no partition into {k} connected panels was found")
    _, labels = np.unique(best, return_inverse=True)
    by_area = np.argsort(-np.bincount(labels, weights=area))
    return np.argsort(by_area)[labels]


def panel_submesh(V: np.ndarray, F: np.ndarray, labels: np.ndarray, panel: int
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The faces of one panel as a mesh of their own.

    Returns
    -------
    Vp : (p, 3) its vertices; Fp : (q, 3) its faces; vertex_index : (p,) each vertex's index in V;
    face_index : (q,) each face's index in F.
    """
    face_index = np.flatnonzero(labels == panel)
    if face_index.size == 0:
        raise ValueError(f"panel {panel} has no faces")
    vertex_index, inverse = np.unique(F[face_index], return_inverse=True)
    return V[vertex_index], inverse.reshape(-1, 3).astype(np.int64), vertex_index, face_index


def boundary_loops(F: np.ndarray) -> list[np.ndarray]:
    """The boundary loops of a mesh (a topological disk has exactly one)."""
    import igl
    return [np.asarray(loop, dtype=np.int64) for loop in igl.boundary_loop_all(np.asarray(F, dtype=np.int64))]


def bisect(labels: np.ndarray, panel: int, pairs: np.ndarray, weights: np.ndarray, area: np.ndarray,
           across: np.ndarray | None = None) -> np.ndarray:
    """Split one panel in two of equal area along a level set: of its own Fiedler vector (the cheapest
    balanced cut of that panel), or of ``across``; the new panel gets the next free number.

    Parameters
    ----------
    labels : (m,) panel of each face; panel : the one to split; pairs, weights, area : the face graph.
    across : (m,) a per-face value to split at the median of instead (a panel too large for the frame
        is cut across its longest extent: the Fiedler vector of a sector is another sector).

    Returns
    -------
    (m,) the new labels (each panel one connected piece).
    """
    faces = np.flatnonzero(labels == panel)
    if len(faces) < 4:
        raise ValueError(f"panel {panel} has {len(faces)} faces: too few to split")
    inside = (labels[pairs[:, 0]] == panel) & (labels[pairs[:, 1]] == panel)
    local = np.full(len(labels), -1)
    local[faces] = np.arange(len(faces))
    sub_pairs = local[pairs[inside]]
    value = (spectral_embedding(sub_pairs, weights[inside], area[faces], 1)[:, 0] if across is None
             else across[faces])
    order = np.argsort(value)
    half = np.searchsorted(np.cumsum(area[faces][order]), 0.5 * area[faces].sum())
    new = labels.copy()
    new[faces[order[half + 1:]]] = labels.max() + 1
    return _merge_fragments(_smooth(new, pairs, weights), pairs, weights, area)


def longest_axis(centroids: np.ndarray, area: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m,) each face's coordinate along the longest principal axis of the given faces (k,) (their
    area-weighted centroids (m, 3)): the value to cut a panel across its longest extent."""
    P = centroids[faces]
    w = area[faces] / area[faces].sum()
    c = (w[:, None] * P).sum(axis=0)
    cov = ((P - c) * w[:, None]).T @ (P - c)
    axis = np.linalg.eigh(cov)[1][:, -1]
    return (centroids - c) @ axis


def _seam_graph(F: np.ndarray, labels: np.ndarray, n: int) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """The seams as a vertex graph (n × n adjacency of the edges between panels), the seam vertices that
    may move (not where three panels meet, where a seam meets the target's boundary, chain ends) and
    the target's boundary vertices."""
    pairs, verts = interior_edges(F)
    seam = verts[labels[pairs[:, 0]] != labels[pairs[:, 1]]]
    A = sp.coo_matrix((np.ones(2 * len(seam)), (np.r_[seam[:, 0], seam[:, 1]], np.r_[seam[:, 1], seam[:, 0]])),
                      shape=(n, n)).tocsr()
    degree = np.asarray(A.sum(axis=1)).ravel()
    on_rim = np.zeros(n, dtype=bool)
    for loop in boundary_loops(F):
        on_rim[loop] = True
    vertex_panels = sp.coo_matrix((np.ones(F.size), (F.ravel(), np.repeat(labels, 3))), shape=(n, labels.max() + 1))
    junction = np.asarray((vertex_panels.tocsr() > 0).sum(axis=1)).ravel() >= 3
    movable = (degree == 2) & ~on_rim & ~junction
    return A, movable, on_rim


def straighten_seams(V: np.ndarray, F: np.ndarray, labels: np.ndarray, passes: int = 30) -> np.ndarray:
    """Slide the seams' vertices along the surface so that each seam runs smooth, not along the mesh's
    zigzag: a seam cut along mesh edges is a staircase as long as 1.1-1.3 × the curve it follows.

    Each pass moves a seam vertex half way to the midpoint of its two seam neighbours, then a band of
    two rings around the seams is relaxed the same way over the mesh (so no triangle is left a sliver),
    and every moved vertex is put back onto the original surface (its closest point). A move that would
    turn a face over is undone. Junctions, chain ends and the target's boundary stay.

    Parameters
    ----------
    V : (n, 3) vertices; F : (m, 3) faces; labels : (m,) panel of each face.

    Returns
    -------
    (n, 3) the vertices with straighter seams (the same mesh, on the same surface).
    """
    import igl
    n = len(V)
    A, movable, on_rim = _seam_graph(F, labels, n)
    degree = np.maximum(np.asarray(A.sum(axis=1)).ravel(), 1)
    E = np.r_[F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]
    M = sp.coo_matrix((np.ones(len(E) * 2), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n)).tocsr()
    M.data[:] = 1.0
    ring = (M @ (M @ movable.astype(float)) > 0) & ~movable
    band = ring & ~on_rim & ~(np.asarray(A.sum(axis=1)).ravel() > 0)
    mdeg = np.maximum(np.asarray(M.sum(axis=1)).ravel(), 1)
    normal0 = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    X = V.copy()
    for _ in range(passes):
        Y = X.copy()
        Y[movable] = 0.5 * X[movable] + 0.5 * (A @ X)[movable] / degree[movable, None]
        Y[band] = 0.5 * Y[band] + 0.5 * (M @ Y)[band] / mdeg[band, None]
        moved = movable | band
        _, _, closest = igl.point_mesh_squared_distance(Y[moved], V, F)
        Y[moved] = closest
        normal = np.cross(Y[F[:, 1]] - Y[F[:, 0]], Y[F[:, 2]] - Y[F[:, 0]])
        size = np.linalg.norm(normal, axis=1)
        cos = (normal * normal0).sum(1) / np.maximum(size * np.linalg.norm(normal0, axis=1), 1e-300)
        bad = np.unique(F[cos < 0.5])
        Y[bad] = X[bad]                                     # undo the moves that turn or crush a face
        X = Y
    return X


def grid_partition(centroids: np.ndarray, area: np.ndarray, rows: int, columns: int, pairs: np.ndarray,
                   weights: np.ndarray) -> np.ndarray:
    """``rows`` × ``columns`` panels of about equal area: strips across the surface's longest principal
    axis, each cut across its second into cells (a surface wider than the frame is tiled, where the
    spectral cut's sectors would be long and thin).

    Parameters
    ----------
    centroids : (m, 3) face centroids; area : (m,) face areas; rows, columns : ≥ 1; pairs, weights : the
    face graph (each panel is made one connected piece).

    Returns
    -------
    (m,) panel index of each face, 0..rows·columns − 1 (fewer when a cell came out empty).
    """
    if rows < 1 or columns < 1:
        raise ValueError(f"grid_partition: rows and columns must be ≥ 1, got {rows} × {columns}")
    w = area / area.sum()
    c = (w[:, None] * centroids).sum(axis=0)
    axes = np.linalg.eigh(((centroids - c) * w[:, None]).T @ (centroids - c))[1]
    u, v = (centroids - c) @ axes[:, -1], (centroids - c) @ axes[:, -2]
    labels = np.empty(len(area), dtype=np.int64)
    strip = _quantile_bins(u, area, rows)
    for r in range(rows):
        faces = np.flatnonzero(strip == r)
        labels[faces] = r * columns + _quantile_bins(v[faces], area[faces], columns)
    _, labels = np.unique(labels, return_inverse=True)
    return _merge_fragments(_smooth(labels, pairs, weights), pairs, weights, area)


def _quantile_bins(x: np.ndarray, area: np.ndarray, n: int) -> np.ndarray:
    """(k,) the bin 0..n−1 of each value so that the bins hold about equal area."""
    order = np.argsort(x)
    cum = np.cumsum(area[order]) / area.sum()
    bins = np.empty(len(x), dtype=np.int64)
    bins[order] = np.minimum((cum * n - 1e-12).astype(np.int64), n - 1)
    return bins
