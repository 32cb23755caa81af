"""Intake of the target surface: clean the mesh and check that it is a topological disk.

The method flattens a single, consistently oriented, manifold disk (one boundary loop, genus 0).
``load_target`` reads a file (``mesh_io.read_mesh``), merges duplicate vertices and drops unused
ones (``clean_mesh``), then validates (``check_disk``); every refusal is a
:class:`~ribbond.design.errors.MeshError` whose ``problem`` says what is wrong and whose message
says where (face indices, vertex indices and coordinates: the first few, plus a count).

All checks are vectorized: half-edges keyed by sorted vertex pairs, ``np.unique`` with counts, and
``scipy.sparse.csgraph.connected_components`` for connected components, per-vertex face fans and
boundary loops.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import igl
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..mesh import files as mesh_io
from .errors import MeshError

__all__ = ["CleanedMesh", "TargetMesh", "check_disk", "clean_mesh", "load_target"]

#: How many offending items a message lists before summarising the rest as a count.
_LIST_LIMIT = 5
#: A face is degenerate when its area is at most this times the squared bounding-box diagonal.
_ZERO_AREA = 1e-12
#: The fewest faces the engine designs: the deployed shape's bending lives on interior edges (two
#: faces sharing an edge, ``ribbond.deploy``), and a single triangle has none.
MIN_FACES = 2


@dataclass(frozen=True, eq=False)
class CleanedMesh:
    """A mesh after merging duplicate vertices and dropping unreferenced ones.

    Attributes
    ----------
    V : (n, 3) float64 array
        vertex positions (a merged group keeps the position of its lowest-numbered vertex).
    F : (m, 3) int64 array
        faces, in the input order, re-indexed into ``V``.
    merged : int
        vertices removed because they were merged into another.
    unreferenced : int
        vertices dropped because no face uses them (counted after merging).
    """

    V: np.ndarray
    F: np.ndarray
    merged: int
    unreferenced: int


@dataclass(frozen=True, eq=False)
class TargetMesh:
    """The validated target surface, ready for the design engine.

    Attributes
    ----------
    V : (n, 3) float64 array
        vertex positions.
    F : (m, 3) int64 array
        faces, consistently oriented, in file order (after triangulation).
    boundary : (b,) int64 array
        the boundary loop, vertex indices in order (as ``igl.boundary_loop``).
    source_faces : int
        triangles in the file after fan triangulation (equal to ``len(F)``: none are dropped).
    merged : int
        duplicate vertices merged away.
    unreferenced : int
        unused vertices dropped.
    sha256 : str
        hex digest of the file's bytes.
    name : str
        the file name.
    """

    V: np.ndarray
    F: np.ndarray
    boundary: np.ndarray
    source_faces: int
    merged: int
    unreferenced: int
    sha256: str
    name: str


# ---------------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------------


def load_target(path: str | Path, *, max_faces: int, merge_tolerance: float = 1e-7) -> TargetMesh:
    """Read, clean and validate the target surface.

    Parameters
    ----------
    path : str or Path
        an OBJ, OFF, STL or PLY file.
    max_faces : int
        refuse meshes with more triangles than this (checked before the body is parsed where the
        format allows).
    merge_tolerance : float
        vertices closer than this times the bounding-box diagonal are merged.

    Returns
    -------
    TargetMesh

    Raises
    ------
    MeshError
        anything ``read_mesh``, ``clean_mesh`` or ``check_disk`` refuses; messages start with the
        file name. Vertex indices in ``check_disk`` messages refer to the cleaned mesh (its
        coordinates are given too); face indices are the file's faces after triangulation.
    """
    name = Path(path).name or str(path)
    V, F, data = mesh_io._read(path, max_faces)
    digest = hashlib.sha256(data).hexdigest()
    cleaned: CleanedMesh | None = None
    try:
        # before cleaning, so that indices are the file's; an OBJ's vertices named as its faces
        # name them (from 1) with their line
        _check_finite(V, F, mesh_io.vertex_lines(data, Path(path).suffix))
        cleaned = clean_mesh(V, F, merge_tolerance=merge_tolerance)
        boundary = check_disk(cleaned.V, cleaned.F)
    except MeshError as exc:
        message = f"{name}: {exc}"
        if exc.problem == "bad_index" and cleaned is not None and cleaned.merged:
            message += (f" (after merging {cleaned.merged} vertices closer than "
                        f"{merge_tolerance:g} × the bounding-box diagonal to another; a smaller "
                        f"merge tolerance may help)")
        raise MeshError(exc.problem, message) from None
    return TargetMesh(V=cleaned.V, F=cleaned.F, boundary=boundary, source_faces=len(F),
                      merged=cleaned.merged, unreferenced=cleaned.unreferenced, sha256=digest,
                      name=name)


def clean_mesh(V: np.ndarray, F: np.ndarray, *, merge_tolerance: float = 1e-7) -> CleanedMesh:
    """Merge duplicate vertices, drop unreferenced ones, keep the faces in order.

    Vertices closer than ``merge_tolerance × d`` (d: the bounding-box diagonal of the finite
    vertices) are merged, transitively; a group keeps the position of its lowest-numbered vertex
    and the surviving vertices keep their relative order. Non-finite vertices are never merged
    (``check_disk`` reports them). Faces that merging makes degenerate are kept, so that
    ``check_disk`` reports them with their original face index.

    Parameters
    ----------
    V : (n, 3) float array
        vertex positions.
    F : (m, 3) int array
        faces, 0-based.
    merge_tolerance : float
        relative merge distance (≥ 0; 0 merges exact duplicates only).

    Returns
    -------
    CleanedMesh

    Raises
    ------
    MeshError
        ``"bad_index"`` if ``V`` or ``F`` has the wrong shape or ``F`` indexes outside ``V``.
    ValueError
        ``merge_tolerance`` is negative or not finite.
    """
    V, F = _as_arrays(V, F)
    n = len(V)
    _check_indices(V, F, repeats=False)
    if not (np.isfinite(merge_tolerance) and merge_tolerance >= 0):
        raise ValueError(f"merge_tolerance must be a finite number ≥ 0, got {merge_tolerance}")

    rep = np.arange(n, dtype=np.int64)  # each vertex's representative (lowest index of its group)
    fi = np.flatnonzero(np.isfinite(V).all(axis=1))
    if fi.size:
        P = V[fi] + 0.0  # + 0.0 turns -0.0 into 0.0, so that np.unique sees them equal
        lo, hi = P.min(axis=0), P.max(axis=0)
        tol = merge_tolerance * float(np.linalg.norm(hi - lo))
        uniq, inv = np.unique(P, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        label = inv
        if tol > 0 and len(uniq) > 1:
            group = _near_groups(uniq, tol, lo)
            label = group[inv]
        # The first member (in vertex order) of each group represents it.
        _, first = np.unique(label, return_index=True)
        rep_of_label = np.empty(label.max() + 1, dtype=np.int64)
        rep_of_label[label[first]] = fi[first]
        rep[fi] = rep_of_label[label]
    distinct = int(np.count_nonzero(rep == np.arange(n)))
    merged = n - distinct

    F2 = rep[F]
    used = np.zeros(n, dtype=bool)
    used[F2.ravel()] = True
    keep = np.flatnonzero(used)
    new_index = np.full(n, -1, dtype=np.int64)
    new_index[keep] = np.arange(len(keep), dtype=np.int64)
    return CleanedMesh(V=V[keep].copy(), F=new_index[F2], merged=merged,
                       unreferenced=distinct - len(keep))


def check_disk(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Check that the mesh is one consistently oriented manifold topological disk.

    Checks, in this order (the first failing one raises):

    - ``"empty"``: no faces;
    - ``"too_small"``: fewer than ``MIN_FACES`` faces (one triangle has no interior edge to bend about);
    - ``"non_finite"``: NaN or infinite coordinates (vertex indices);
    - ``"bad_index"``: face indices outside ``V``, or a face repeating a vertex (face indices);
    - ``"zero_area"``: faces with area ≤ 1e-12 × (bounding-box diagonal)² (faces, centroids);
    - ``"non_manifold_edge"``: an edge shared by more than two faces (its vertices and faces);
    - ``"orientation"``: two faces traversing their shared edge the same way (edges and faces,
      and the fewest faces to reverse, or that the surface is not orientable);
    - ``"non_manifold_vertex"``: a vertex whose faces form more than one fan (vertex, position);
    - ``"components"``: more than one connected component (how many, their face counts);
    - ``"closed"``: no boundary (a closed surface must be cut open to be flattened);
    - ``"not_disk"``: more than one boundary loop or Euler characteristic ≠ 1 (loops, genus).

    Vertices no face uses are ignored.

    Parameters
    ----------
    V : (n, 3) float array
        vertex positions.
    F : (m, 3) int array
        faces, 0-based.

    Returns
    -------
    boundary : (b,) int64 array
        the boundary loop, vertex indices in order (``igl.boundary_loop``).

    Raises
    ------
    MeshError
        with the ``problem`` keys above.
    """
    V, F = _as_arrays(V, F)
    _check_face_count(len(F))
    _check_finite(V, None)
    _check_indices(V, F, repeats=True)
    _check_areas(V, F)
    he = _half_edges(F, len(V))
    _check_edges_manifold(V, he)
    _check_orientation(V, he)
    _check_vertices_manifold(V, he)
    _check_connected(he)
    _check_one_boundary_loop(F, he)
    return np.asarray(igl.boundary_loop(F), dtype=np.int64)


@dataclass(frozen=True, eq=False)
class _HalfEdges:
    """The half-edges of F: half-edge h = 3 f + k runs from F[f, k] to F[f, (k + 1) % 3].

    Attributes
    ----------
    src, dst, face_of : (3m,) where each half-edge starts, ends, and its face.
    order : (3m,) the half-edges sorted by undirected edge (stable); first, counts : (e,) where each
        edge's half-edges start in ``order`` and how many there are.
    h1, h2 : the two half-edges of each interior edge (two faces).
    """

    n: int
    m: int
    src: np.ndarray
    dst: np.ndarray
    face_of: np.ndarray
    order: np.ndarray
    first: np.ndarray
    counts: np.ndarray
    h1: np.ndarray
    h2: np.ndarray


def _half_edges(F: np.ndarray, n: int) -> _HalfEdges:
    """Half-edges keyed by their sorted vertex pair, grouped into edges with ``np.unique``."""
    m = len(F)
    src = F.ravel()
    dst = F[:, [1, 2, 0]].ravel()
    face_of = np.repeat(np.arange(m, dtype=np.int64), 3)
    key = np.minimum(src, dst) * np.int64(n) + np.maximum(src, dst)
    order = np.argsort(key, kind="stable")
    _, first, counts = np.unique(key[order], return_index=True, return_counts=True)
    interior = np.flatnonzero(counts == 2)
    return _HalfEdges(n=n, m=m, src=src, dst=dst, face_of=face_of, order=order, first=first, counts=counts,
                      h1=order[first[interior]], h2=order[first[interior] + 1])


def _check_face_count(m: int) -> None:
    """``"empty"`` and ``"too_small"``."""
    if m == 0:
        raise MeshError("empty", "the mesh has no faces")
    if m < MIN_FACES:
        raise MeshError("too_small", f"the mesh has {_count(m, 'face')}: the engine designs surfaces of at "
                                     f"least {MIN_FACES} faces (a surface's bending lives on the edges two "
                                     "faces share, and a single triangle has none: its deployed shape "
                                     "cannot be predicted); subdivide it or give the whole surface")


def _check_areas(V: np.ndarray, F: np.ndarray) -> None:
    """``"zero_area"``: degenerate faces, relative to the size of the used part of the mesh."""
    P = V[np.unique(F)]
    diag2 = float(np.sum((P.max(axis=0) - P.min(axis=0)) ** 2))
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    zero = np.flatnonzero(area <= _ZERO_AREA * diag2)
    if zero.size:
        centroid = (a[zero] + b[zero] + c[zero]) / 3.0
        items = [f"face {f} (centroid {_xyz(p)})" for f, p in zip(zero[:_LIST_LIMIT], centroid)]
        raise MeshError("zero_area", f"{_count(zero.size, 'face')} with (near) zero area: "
                                     f"{_listing(items, zero.size)}")


def _check_edges_manifold(V: np.ndarray, he: _HalfEdges) -> None:
    """``"non_manifold_edge"``: an edge shared by more than two faces."""
    over = np.flatnonzero(he.counts > 2)
    if over.size:
        items = []
        for e in over[:_LIST_LIMIT]:
            h = he.order[he.first[e]: he.first[e] + he.counts[e]]
            u, v = sorted((int(he.src[h[0]]), int(he.dst[h[0]])))
            items.append(f"edge {u}–{v} ({_xyz(V[u])} – {_xyz(V[v])}) in faces "
                         f"{', '.join(str(f) for f in he.face_of[h])}")
        raise MeshError("non_manifold_edge", f"{_count(over.size, 'edge')} shared by more than two "
                                             f"faces: {_listing(items, over.size)}")


def _check_orientation(V: np.ndarray, he: _HalfEdges) -> None:
    """``"orientation"``: two faces traversing their shared edge the same way."""
    src, dst, face_of, h1, h2 = he.src, he.dst, he.face_of, he.h1, he.h2
    flipped = np.flatnonzero(src[h1] != dst[h2])
    if flipped.size:
        items = [f"edge {src[h1[i]]}→{dst[h1[i]]} at {_xyz(V[src[h1[i]]])} – "
                 f"{_xyz(V[dst[h1[i]]])}, traversed the same way by faces {face_of[h1[i]]} and "
                 f"{face_of[h2[i]]}" for i in flipped[:_LIST_LIMIT]]
        raise MeshError("orientation", f"inconsistent orientation: {_count(flipped.size, 'edge')} "
                                       f"where neighbouring faces disagree: "
                                       f"{_listing(items, flipped.size)}; "
                                       f"{_winding_advice(he.m, face_of[h1], face_of[h2], flipped)}")


def _check_vertices_manifold(V: np.ndarray, he: _HalfEdges) -> None:
    """``"non_manifold_vertex"``: a vertex whose faces form more than one fan.

    Corners (one per half-edge start) of the same vertex are joined across each interior edge; a
    manifold vertex has all its corners in one fan.
    """
    def nxt(h: np.ndarray) -> np.ndarray:
        return h - h % 3 + (h % 3 + 1) % 3

    h1, h2 = he.h1, he.h2
    a_corners = np.concatenate([h1, nxt(h1)])  # corner of src(h1), corner of dst(h1)
    b_corners = np.concatenate([nxt(h2), h2])  # corner of dst(h2) = src(h1), of src(h2) = dst(h1)
    n_fans, fan = _components(3 * he.m, a_corners, b_corners)
    vertex_fan = np.unique(he.src * np.int64(n_fans) + fan)
    fans_per_vertex = np.bincount(vertex_fan // n_fans, minlength=he.n)
    pinched = np.flatnonzero(fans_per_vertex > 1)
    if pinched.size:
        items = [f"vertex {v} at {_xyz(V[v])} ({fans_per_vertex[v]} fans)"
                 for v in pinched[:_LIST_LIMIT]]
        raise MeshError("non_manifold_vertex", f"{_count(pinched.size, 'vertex', 'vertices')} "
                                               f"where separate fans of faces touch (a 'bow-tie'): "
                                               f"{_listing(items, pinched.size)}")


def _check_connected(he: _HalfEdges) -> None:
    """``"components"``: more than one connected component."""
    n_comp, comp = _components(he.m, he.face_of[he.h1], he.face_of[he.h2])
    if n_comp > 1:
        sizes = np.bincount(comp, minlength=n_comp)
        sizes_desc = np.sort(sizes)[::-1]
        shown = ", ".join(str(s) for s in sizes_desc[:_LIST_LIMIT])
        more = f", … ({n_comp - _LIST_LIMIT} more)" if n_comp > _LIST_LIMIT else ""
        smallest = int(np.argmin(sizes))
        example = int(np.flatnonzero(comp == smallest)[0])
        raise MeshError("components", f"the mesh has {n_comp} separate connected components "
                                      f"(faces per component: {shown}{more}; e.g. face {example} "
                                      f"is in one with {sizes[smallest]} faces); the target must "
                                      f"be a single piece")


def _check_one_boundary_loop(F: np.ndarray, he: _HalfEdges) -> None:
    """``"closed"`` (no boundary) and ``"not_disk"`` (more than one boundary loop, or genus)."""
    m, n_edges = he.m, len(he.first)
    border = he.order[he.first[he.counts == 1]]
    if border.size == 0:
        raise MeshError("closed", f"the surface is closed (no boundary edges; {m} faces, Euler "
                                  f"characteristic {_n_used(F) - n_edges + m}); it must be cut "
                                  f"open into a topological disk to be flattened")
    chi = _n_used(F) - n_edges + m
    _, loop_label = _components(he.n, he.src[border], he.dst[border])
    loops = len(np.unique(loop_label[he.src[border]]))
    genus2 = 2 - loops - chi  # χ = 2 − 2g − b for a connected orientable surface
    if loops != 1 or chi != 1:
        genus = genus2 // 2
        holes = loops - 1
        raise MeshError("not_disk", f"the surface is not a topological disk: it has "
                                    f"{_count(loops, 'boundary loop')} ({_count(holes, 'hole')} "
                                    f"besides the outer boundary) and genus {genus} (Euler "
                                    f"characteristic {chi}, a disk has 1); it needs cuts to become a "
                                    f"topological disk, which is what the method flattens")


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------


def _n_used(F: np.ndarray) -> int:
    """Number of distinct vertices the faces use."""
    return len(np.unique(F))


def _as_arrays(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    try:
        V = np.asarray(V, dtype=np.float64)
        F_in = np.asarray(F)
    except (TypeError, ValueError) as exc:
        raise MeshError("bad_index", f"V and F must be numeric arrays: {exc}") from None
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError("bad_index", f"V must be an (n, 3) array of positions, got shape {V.shape}")
    if F_in.size == 0:
        return V, np.zeros((0, 3), dtype=np.int64)
    if F_in.ndim != 2 or F_in.shape[1] != 3:
        raise MeshError("bad_index", f"F must be an (m, 3) array of triangles, got shape "
                                     f"{F_in.shape}")
    if not np.issubdtype(F_in.dtype, np.integer):
        if not (np.issubdtype(F_in.dtype, np.floating) and np.all(np.isfinite(F_in))
                and np.all(F_in == np.round(F_in))):
            raise MeshError("bad_index", f"F must hold integer vertex indices, got {F_in.dtype}")
    return V, np.ascontiguousarray(F_in, dtype=np.int64)


def _check_finite(V: np.ndarray, F: np.ndarray | None, lines: np.ndarray | None = None) -> None:
    """``non_finite`` for vertices with NaN/inf coordinates (only those ``F`` uses, if given).
    ``lines``: (n,) the file's line of each vertex (an OBJ's): each is then named by its line and
    its number from 1, as the file's faces refer to it."""
    bad = ~np.isfinite(V).all(axis=1)
    if F is not None and bad.any():
        inside = F[(F >= 0) & (F < len(V))]
        used = np.zeros(len(V), dtype=bool)
        used[inside] = True
        bad &= used
    idx = np.flatnonzero(bad)
    if idx.size:
        if lines is not None and len(lines) == len(V):
            items = [f"vertex {v + 1} on line {lines[v]} at {_xyz(V[v])}" for v in idx[:_LIST_LIMIT]]
        else:
            items = [f"vertex {v} at {_xyz(V[v])}" for v in idx[:_LIST_LIMIT]]
        raise MeshError("non_finite", f"{_count(idx.size, 'vertex', 'vertices')} with NaN or "
                                      f"infinite coordinates: {_listing(items, idx.size)}")


def _check_indices(V: np.ndarray, F: np.ndarray, *, repeats: bool) -> None:
    """``bad_index`` for out-of-range face indices and (optionally) faces repeating a vertex."""
    n = len(V)
    out = (F < 0) | (F >= n)
    rows = np.flatnonzero(out.any(axis=1))
    if rows.size:
        items = [f"face {f} refers to vertex {int(F[f][out[f]][0])}" for f in rows[:_LIST_LIMIT]]
        raise MeshError("bad_index", f"{_count(rows.size, 'face')} with vertex indices outside "
                                     f"0…{n - 1}: {_listing(items, rows.size)}")
    if repeats:
        same = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
        rows = np.flatnonzero(same)
        if rows.size:
            items = [f"face {f} ({F[f, 0]}, {F[f, 1]}, {F[f, 2]}) at {_xyz(V[F[f]].mean(axis=0))}"
                     for f in rows[:_LIST_LIMIT]]
            raise MeshError("bad_index", f"{_count(rows.size, 'face')} that repeats a vertex: "
                                         f"{_listing(items, rows.size)}")


def _winding_advice(m: int, f1: np.ndarray, f2: np.ndarray, disagree: np.ndarray) -> str:
    """Which faces to reverse to make the winding consistent (the fewest per component), or that
    none can: the end of the ``"orientation"`` message.

    ``f1[i]``, ``f2[i]`` are the two faces of interior edge i; ``disagree`` indexes the edges they
    traverse the same way.

    Node f means "face f kept", node m + f "face f reversed"; neighbours that agree link kept to
    kept, neighbours that disagree link kept to reversed. A face linked to its own reversal lies on
    a non-orientable surface; otherwise each component and its mirror are the two windings.
    """
    agree = np.ones(len(f1), dtype=bool)
    agree[disagree] = False
    a = np.concatenate([f1, f1 + m])
    b = np.concatenate([np.where(agree, f2, f2 + m), np.where(agree, f2 + m, f2)])
    _, label = _components(2 * m, a, b)
    kept, rev = label[:m], label[m:]
    if np.any(kept == rev):
        return ("the surface is not orientable (like a Möbius strip): no winding of its faces "
                "can be consistent, and it must be cut to become a topological disk")
    flips = np.bincount(rev, minlength=label.max() + 1)  # faces reversed by choosing a component
    # Face f is reversed if the mirror winding (the component of m + f) reverses fewer faces.
    reverse = np.flatnonzero((flips[rev] < flips[kept]) | ((flips[rev] == flips[kept]) & (rev < kept)))
    shown = ", ".join(str(f) for f in reverse[:_LIST_LIMIT])
    more = f" and {reverse.size - _LIST_LIMIT} more" if reverse.size > _LIST_LIMIT else ""
    return (f"the file's faces need a consistent winding (all counter-clockwise seen from the "
            f"same side of the surface): reversing {_count(reverse.size, 'face')} "
            f"({shown}{more}) would give one")


def _near_groups(P: np.ndarray, tol: float, lo: np.ndarray) -> np.ndarray:
    """Group labels for distinct points ``P`` (k, 3) chained by distances ≤ ``tol``.

    Uses a k-d tree's close pairs; if a pathological cluster would give too many pairs, falls back
    to snapping to a grid of cell ``tol`` (O(k log k) whatever the input).
    """
    tree = cKDTree(P)
    k = len(P)
    pairs_upper = (tree.count_neighbors(tree, tol) - k) // 2
    if pairs_upper <= 20 * k + 1000:
        pairs = tree.query_pairs(tol, output_type="ndarray")
        if len(pairs) == 0:
            return np.arange(k, dtype=np.int64)
        _, label = _components(k, pairs[:, 0], pairs[:, 1])
        return label
    cells = np.floor((P - lo) / tol).astype(np.int64)
    _, label = np.unique(cells, axis=0, return_inverse=True)
    return label.reshape(-1).astype(np.int64)


def _components(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the undirected graph on ``n`` nodes with edges ``a[i]–b[i]``."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n)).tocsr()
    count, label = connected_components(graph, directed=False)
    return int(count), label.astype(np.int64)


def _xyz(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{float(x):.6g}" for x in p) + ")"


def _count(k: int, singular: str, plural: str | None = None) -> str:
    return f"{k} {singular if k == 1 else (plural or singular + 's')}"


def _listing(items: list[str], total: int) -> str:
    text = "; ".join(items)
    if total > len(items):
        text += f"; and {total - len(items)} more"
    return text
