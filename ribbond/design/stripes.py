"""Stripe patterns on the flat surface (§6.2; Knöppel, Crane, Pinkall, Schröder 2015).

A stripe pattern is a unit complex field ψ on the vertices whose phase arg ψ advances by
ν ⟨X, dx⟩ along a direction field X with frequency ν = 2π / period. KCPS15 find it as the
smallest eigenvector of a stripe energy against the mass matrix,

    E(ψ) = Σ_edges w_ij |ψ_j^(s_ij) − e^{i ω_ij} ψ_i|²,    ω_ij = ½ (ν_i ⟨X_i, e_ij⟩ + s_ij ν_j ⟨X_j, e_ij⟩),

with cotangent weights w_ij and vertex areas as the mass. X is a line field (X and −X are the same
line), so each vertex keeps one representative; where the representatives of an edge point
opposite ways (s_ij = −1) the field at j is taken conjugated (ψ^(−1) = ψ̄), which makes E real-linear:
it is solved as a 2n × 2n real system. The eigenvector comes from inverse power iteration on the
factorized matrix.

The phase is integrated per edge (the edge's ω plus the small correction that ψ itself asks for),
so a triangle's corners get consistent phases unless the phase winds around it (a singularity of
the pattern) or the line field turns over inside it; such triangles carry no isolines.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from .linalg import SymmetricFactor

TWO_PI = 2.0 * np.pi

#: Cotangent weights below this are raised to it: obtuse triangles give negative weights,
#: which would make the energy indefinite (any positive weights still give a consistent energy).
_MIN_WEIGHT = 1e-3


@dataclass(frozen=True)
class EdgeTopology:
    """The undirected edges of a triangle mesh and how faces use them.

    Attributes
    ----------
    edges : (E, 2) vertex pairs i < j.
    face_edges : (m, 3) the edge of half-edge k of each face, F[f, k] → F[f, (k + 1) % 3].
    forward : (m, 3) True where that half-edge runs i → j (low to high vertex).
    faces_per_edge : (E,) 1 on the boundary, 2 inside.
    """

    edges: np.ndarray
    face_edges: np.ndarray
    forward: np.ndarray
    faces_per_edge: np.ndarray


def edge_topology(F: np.ndarray) -> EdgeTopology:
    """The undirected edges of ``F`` (m, 3) and the face-to-edge incidence."""
    he = np.stack([F, np.roll(F, -1, axis=1)], axis=2).reshape(-1, 2)
    lo, hi = he.min(axis=1), he.max(axis=1)
    n = int(F.max()) + 1
    key = lo.astype(np.int64) * n + hi
    uniq, inverse = np.unique(key, return_inverse=True)
    edges = np.column_stack([uniq // n, uniq % n]).astype(np.int64)
    return EdgeTopology(edges=edges, face_edges=inverse.reshape(-1, 3),
                        forward=(he[:, 0] == lo).reshape(-1, 3),
                        faces_per_edge=np.bincount(inverse, minlength=len(uniq)))


def vertex_average(F: np.ndarray, values: np.ndarray, face_area: np.ndarray, n: int) -> np.ndarray:
    """Area-weighted average at the vertices of per-face ``values`` (m,) or (m, k) (§6.2)."""
    w = np.repeat(face_area, 3)
    total = np.bincount(F.ravel(), weights=w, minlength=n)
    vals = np.repeat(np.asarray(values, dtype=float), 3, axis=0)
    if vals.ndim == 1:
        return np.bincount(F.ravel(), weights=w * vals, minlength=n) / total
    return np.column_stack([np.bincount(F.ravel(), weights=w * vals[:, c], minlength=n)
                            for c in range(vals.shape[1])]) / total[:, None]


def vertex_line_field(F: np.ndarray, directions: np.ndarray, face_area: np.ndarray, n: int) -> np.ndarray:
    """A unit representative (n, 2) at each vertex of the per-face line field ``directions`` (m, 2).

    Lines are averaged in the squared representation z² (where d and −d agree), area-weighted.
    """
    z = (directions[:, 0] + 1j * directions[:, 1]) ** 2
    avg = vertex_average(F, np.column_stack([z.real, z.imag]), face_area, n)
    half = 0.5 * np.arctan2(avg[:, 1], avg[:, 0])
    return np.column_stack([np.cos(half), np.sin(half)])


def face_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m,) unsigned areas of the flat triangles."""
    a, b = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def anisotropic_weights(uv: np.ndarray, F: np.ndarray, topology: EdgeTopology, along: np.ndarray,
                        ratio: float) -> np.ndarray:
    """Edge weights (E,) of the Dirichlet energy ∫ ∇uᵀ D ∇u, D = n nᵀ + ratio · t tᵀ per face with
    t = ``along`` (m, 2) unit and n ⟂ t (gradients along t cost ``ratio`` times those across);
    ratio = 1 gives the cotangent weights. Raised to at least ``_MIN_WEIGHT`` like those."""
    P = uv[F]                                            # (m, 3, 2)
    e = np.roll(P, -1, axis=1) - np.roll(P, 1, axis=1)   # the edge opposite corner k
    g = np.stack([-e[..., 1], e[..., 0]], axis=-1)       # ∝ ∇φ_k (the factor 1/(2A) below)
    a2 = np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
    gt = np.einsum("fkc,fc->fk", g, along)
    K = (np.einsum("fkc,flc->fkl", g, g) + (ratio - 1.0) * gt[:, :, None] * gt[:, None, :]) \
        / (2.0 * np.maximum(a2, 1e-300))[:, None, None]
    k = np.arange(3)
    w = np.bincount(topology.face_edges.ravel(), weights=-K[:, k, (k + 1) % 3].ravel(),
                    minlength=len(topology.edges))
    return np.maximum(w, _MIN_WEIGHT)


def cotangent_weights(uv: np.ndarray, F: np.ndarray, topology: EdgeTopology) -> np.ndarray:
    """w_ij = ½ Σ cot of the angles opposite each edge (E,), raised to at least ``_MIN_WEIGHT``."""
    P = uv[F]                                            # (m, 3, 2)
    a = np.roll(P, -1, axis=1) - P                       # corner k -> k+1
    b = np.roll(P, 1, axis=1) - P                        # corner k -> k-1
    cross = np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    cot = np.einsum("fkc,fkc->fk", a, b) / np.maximum(cross, 1e-300)   # at corner k
    # half-edge k (F[k] -> F[k+1]) is opposite corner k + 2
    opposite = np.roll(cot, -2, axis=1)
    w = 0.5 * np.bincount(topology.face_edges.ravel(), weights=opposite.ravel(),
                          minlength=len(topology.edges))
    return np.maximum(w, _MIN_WEIGHT)


@dataclass(frozen=True)
class Isolines:
    """The isolines arg ψ = level (mod 2π) of a stripe pattern, as crossings and segments.

    Attributes
    ----------
    points : (N, 2) where an isoline crosses a mesh edge.
    edge : (N,) that edge; t : (N,) position along it from its low vertex (0..1).
    segments : (S, 2) crossings joined inside a face; segment_face : (S,) that face.
    """

    points: np.ndarray
    edge: np.ndarray
    t: np.ndarray
    segments: np.ndarray
    segment_face: np.ndarray


@dataclass(frozen=True)
class StripePattern:
    """A stripe pattern: ψ at the vertices with its phase integrated along the edges.

    Attributes
    ----------
    psi : (n,) complex, the eigenvector (phase in each vertex's own orientation X_i).
    direction : (n, 2) X_i, the representative of the line field the phase advances along.
    frequency : (n,) ν_i = 2π / period, radians per mm.
    edge_phase : (E,) phase advance from i to j along each edge, in i's orientation.
    flip : (E,) True where X_i and X_j point opposite ways (s_ij = −1).
    singular : (m,) faces the isolines leave out: the phase winds, or the line field turns over.
    eigenvalue : E(ψ) / ‖ψ‖²_M at the end of the iteration.
    iterations : inverse power iterations taken.
    """

    psi: np.ndarray
    direction: np.ndarray
    frequency: np.ndarray
    edge_phase: np.ndarray
    flip: np.ndarray
    singular: np.ndarray
    eigenvalue: float
    iterations: int
    topology: EdgeTopology
    uv: np.ndarray
    F: np.ndarray

    def phase_on_edges(self, edge: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The phase at points ``t`` (k,) along ``edge`` (k,), in the edge's low vertex orientation."""
        i = self.topology.edges[edge, 0]
        return np.angle(self.psi[i]) + t * self.edge_phase[edge]

    def corner_phases(self) -> np.ndarray:
        """(m, 3) phases at the corners of each face, continuous inside the face, in corner 0's orientation.

        Inside a non-singular face the phase is the linear interpolation of these (KCPS15 §5).
        """
        d, sigma = self._half_edge_phases()
        alpha = np.empty(self.F.shape)
        alpha[:, 0] = np.angle(self.psi[self.F[:, 0]])
        alpha[:, 1] = alpha[:, 0] + d[:, 0]
        alpha[:, 2] = alpha[:, 1] + sigma[:, 1] * d[:, 1]
        return alpha

    def _half_edge_phases(self) -> tuple[np.ndarray, np.ndarray]:
        """Phase advance along each half-edge in its tail's orientation (m, 3), and each corner's
        orientation relative to corner 0 (m, 3), ±1."""
        return _half_edge_phases(self.topology, self.edge_phase, self.flip)

    def isolines(self, level: float) -> Isolines:
        """The isolines arg ψ ≡ ``level`` (mod 2π); ``level`` must be 0 or π, the levels a line field
        (ψ up to conjugation) leaves unchanged."""
        if not (level == 0.0 or level == np.pi):
            raise ValueError(f"isolines of a line-field stripe pattern are defined for levels 0 and π, "
                             f"not {level!r}")
        return _isolines(self, level)


def _half_edge_phases(topology: EdgeTopology, edge_phase: np.ndarray,
                      flip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    fe = topology.face_edges
    s = np.where(flip[fe], -1.0, 1.0)                               # (m, 3)
    d = np.where(topology.forward, edge_phase[fe], -s * edge_phase[fe])
    sigma = np.ones_like(s)
    sigma[:, 1] = s[:, 0]
    sigma[:, 2] = s[:, 0] * s[:, 1]
    return d, sigma


class StripeSolver:
    """Stripe patterns on one flat mesh: topology, cotangent weights and mass set up once.

    Parameters
    ----------
    uv : (n, 2) the flat surface, mm.
    F : (m, 3) faces, counter-clockwise.
    """

    def __init__(self, uv: np.ndarray, F: np.ndarray) -> None:
        uv = np.asarray(uv, dtype=float)
        F = np.asarray(F, dtype=np.int64)
        if uv.ndim != 2 or uv.shape[1] != 2:
            raise ValueError(f"uv must have shape (n, 2), got {uv.shape}")
        if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
            raise ValueError(f"F must have shape (m, 3) with m ≥ 1, got {F.shape}")
        self.uv, self.F, self.n = uv, F, len(uv)
        self.topology = edge_topology(F)
        self.weights = cotangent_weights(uv, F, self.topology)
        area = face_areas(uv, F)
        self.vertex_area = np.bincount(F.ravel(), weights=np.repeat(area / 3.0, 3), minlength=self.n)
        self.edge_vector = uv[self.topology.edges[:, 1]] - uv[self.topology.edges[:, 0]]
        self.mass = sp.diags(np.repeat(self.vertex_area, 2)).tocsc()
        extent = float(np.linalg.norm(uv.max(axis=0) - uv.min(axis=0)))
        self._shift = 1e-3 / max(extent, 1e-12) ** 2   # keeps A + εM definite; far below any λ2

    def edge_rotations(self, direction: np.ndarray, frequency: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ω_ij (E,) and the sign flips s_ij = −1 (E,) of the stripe energy for this field."""
        i, j = self.topology.edges.T
        flip = np.einsum("ec,ec->e", direction[i], direction[j]) < 0
        s = np.where(flip, -1.0, 1.0)
        e = self.edge_vector
        omega = 0.5 * (frequency[i] * np.einsum("ec,ec->e", direction[i], e)
                       + s * frequency[j] * np.einsum("ec,ec->e", direction[j], e))
        return omega, flip

    def energy_matrix(self, omega: np.ndarray, flip: np.ndarray,
                      weights: np.ndarray | None = None) -> sp.csc_matrix:
        """The stripe energy as a real symmetric (2n, 2n) matrix, ψ_i ↦ (Re, Im) at rows 2i, 2i + 1."""
        i, j = self.topology.edges.T
        w = self.weights if weights is None else weights
        c, sn = np.cos(omega), np.sin(omega)
        s = np.where(flip, -1.0, 1.0)
        # S R(ω) with S = diag(1, s): the block coupling x_j to x_i, A_ji = −w S R, A_ij = A_jiᵀ
        SR = np.stack([np.stack([c, -sn], axis=1), np.stack([s * sn, s * c], axis=1)], axis=1)  # (E, 2, 2)
        shape = (len(w), 2, 2)
        rows_ji = np.broadcast_to(2 * j[:, None, None] + np.arange(2)[None, :, None], shape)
        cols_ji = np.broadcast_to(2 * i[:, None, None] + np.arange(2)[None, None, :], shape)
        vals = -w[:, None, None] * SR
        diag = np.bincount(np.concatenate([i, j]), weights=np.concatenate([w, w]), minlength=self.n)
        rows = np.concatenate([rows_ji.ravel(), cols_ji.ravel(), np.arange(2 * self.n)])
        cols = np.concatenate([cols_ji.ravel(), rows_ji.ravel(), np.arange(2 * self.n)])
        data = np.concatenate([vals.ravel(), vals.ravel(), np.repeat(diag, 2)])
        return sp.csc_matrix((data, (rows, cols)), shape=(2 * self.n, 2 * self.n))

    def solve(self, direction: np.ndarray, frequency: np.ndarray, *, tolerance: float = 1e-6,
              max_iterations: int = 400, ratio: float = 1.0,
              face_direction: np.ndarray | None = None) -> StripePattern:
        """The stripe pattern along the line field ``direction`` (n, 2) with ``frequency`` (n,) rad/mm.

        Inverse power iteration x ← (A + εM)⁻¹ M x, M-normalized, until the Rayleigh quotient
        changes by less than ``tolerance`` relative to the mean ν² and ψ itself by less than
        ``tolerance`` (1 − |⟨ψ_k, ψ_{k−1}⟩_M|, its global phase aside). The smallest eigenvalues of a
        curved field lie close together: stopped on the Rayleigh quotient alone (2-4 iterations), ψ
        was still a mix of them that depended on the start (a hemisphere's predicted ∫K 62 % or 10 %
        of the target's by the start alone); converged (70-120 iterations there), 11 and 10 %.

        The pattern's global phase is free (every e^{ic} ψ has the same energy), so it is the start's:
        the plane wave ψ_i = exp(i ν_i X_i · (x_i − x̄)), x̄ the flat mesh's centroid. Turning a
        representative X_i over conjugates both the start and the solution at i, so the pattern does
        not depend on the representatives, and it moves continuously with the flat mesh; a uniform
        field gets its line of phase 0 through the centroid. (A random start made the phase depend on
        each X_i's sign: a field along ±90° took its signs from rounding, and a flattening moved by
        4e-7 mm moved the cylinder's rows by a fifth of a period and its dashes by a quarter.)
        """
        direction = np.asarray(direction, dtype=float)
        frequency = np.asarray(frequency, dtype=float)
        if direction.shape != (self.n, 2):
            raise ValueError(f"direction must have shape ({self.n}, 2), got {direction.shape}")
        if frequency.shape != (self.n,) or not np.all(np.isfinite(frequency)) or np.any(frequency <= 0):
            raise ValueError("frequency must be finite and positive at every vertex")
        omega, flip = self.edge_rotations(direction, frequency)
        weights = None
        if ratio != 1.0:
            if face_direction is None:
                raise ValueError("an anisotropic stripe energy (ratio != 1) needs face_direction")
            weights = anisotropic_weights(self.uv, self.F, self.topology, face_direction, ratio)
        A = self.energy_matrix(omega, flip, weights)
        factor = SymmetricFactor(A + self._shift * self.mass)
        m = np.repeat(self.vertex_area, 2)
        centroid = (self.vertex_area @ self.uv) / self.vertex_area.sum()
        wave = frequency * np.einsum("nc,nc->n", direction, self.uv - centroid)
        x = np.column_stack([np.cos(wave), np.sin(wave)]).ravel()
        x /= np.sqrt(np.dot(x, m * x))
        scale = float(np.mean(frequency ** 2))
        lam_prev = np.inf
        it = 0
        for it in range(1, max_iterations + 1):
            previous = x
            x = factor.solve(m * x)
            x /= np.sqrt(np.dot(x, m * x))
            lam = float(x @ (A @ x))
            # |⟨ψ_k, ψ_{k−1}⟩_M| from the real pairs: Σ m (a·b) and Σ m (a × b) per vertex
            dot = float(np.dot(m * previous, x))
            cross = float(np.dot(m[0::2], previous[0::2] * x[1::2] - previous[1::2] * x[0::2]))
            if abs(lam - lam_prev) <= tolerance * scale and 1.0 - np.hypot(dot, cross) <= tolerance:
                break
            lam_prev = lam
        psi = x[0::2] + 1j * x[1::2]
        i, j = self.topology.edges.T
        psi_j = np.where(flip, np.conj(psi[j]), psi[j])
        edge_phase = omega + np.angle(psi_j * np.conj(np.exp(1j * omega) * psi[i]))
        singular = _singular_faces(self.topology, edge_phase, flip)
        return StripePattern(psi=psi, direction=direction, frequency=frequency, edge_phase=edge_phase,
                             flip=flip, singular=singular, eigenvalue=lam, iterations=it,
                             topology=self.topology, uv=self.uv, F=self.F)


def _singular_faces(topology: EdgeTopology, edge_phase: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """Faces where the line field turns over or the phase winds by a nonzero multiple of 2π."""
    d, sigma = _half_edge_phases(topology, edge_phase, flip)
    s_last = np.where(flip[topology.face_edges[:, 2]], -1.0, 1.0)
    turned = sigma[:, 2] * s_last < 0
    winding = np.rint((d * sigma).sum(axis=1) / TWO_PI)
    return turned | (winding != 0)


def _level_range(lo: np.ndarray, hi: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray]:
    """The k with lo < level + 2πk ≤ hi: (first k, count)."""
    k_lo = np.floor((lo - level) / TWO_PI).astype(np.int64) + 1
    k_hi = np.floor((hi - level) / TWO_PI).astype(np.int64)
    return k_lo, np.maximum(k_hi - k_lo + 1, 0)


def _isolines(p: StripePattern, level: float) -> Isolines:
    top = p.topology
    edges = top.edges
    # crossings on every edge, in the edge's own orientation: φ(t) = α_i + t Δ
    a_i = np.angle(p.psi[edges[:, 0]])
    a_j = a_i + p.edge_phase
    k_lo, count = _level_range(np.minimum(a_i, a_j), np.maximum(a_i, a_j), level)
    offset = np.concatenate([[0], np.cumsum(count)])
    owner = np.repeat(np.arange(len(edges)), count)
    k = k_lo[owner] + (np.arange(offset[-1]) - offset[owner])
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (level + TWO_PI * k - a_i[owner]) / p.edge_phase[owner]
    t = np.clip(t, 0.0, 1.0)
    ei, ej = edges[owner, 0], edges[owner, 1]
    points = p.uv[ei] + t[:, None] * (p.uv[ej] - p.uv[ei])

    # segments: in each regular face the linear phase crosses each level on exactly two edges
    alpha = p.corner_phases()
    regular = np.flatnonzero(~p.singular)
    al = alpha[regular]
    f_lo, f_count = _level_range(al.min(axis=1), al.max(axis=1), level)
    seg_nodes, seg_faces = [], []
    for r in range(int(f_count.max(initial=0))):
        sel = np.flatnonzero(f_count > r)
        faces = regular[sel]
        L = level + TWO_PI * (f_lo[sel] + r)
        a0 = al[sel]
        a1 = np.roll(a0, -1, axis=1)
        crosses = (a0 >= L[:, None]) != (a1 >= L[:, None])          # (q, 3), two per row
        with np.errstate(divide="ignore", invalid="ignore"):
            t_face = np.where(crosses, (L[:, None] - a0) / (a1 - a0), 0.0)
        fwd = top.forward[faces]
        t_edge = np.where(fwd, t_face, 1.0 - t_face)
        e = top.face_edges[faces]
        k_edge = np.rint((np.angle(p.psi[edges[e, 0]]) + t_edge * p.edge_phase[e] - level) / TWO_PI)
        k_edge = k_edge.astype(np.int64)
        valid = crosses & (k_edge >= k_lo[e]) & (k_edge < k_lo[e] + count[e])
        node = offset[e] + k_edge - k_lo[e]
        ok = valid.sum(axis=1) == 2
        pick = np.argsort(~valid[ok], axis=1, kind="stable")[:, :2]
        seg_nodes.append(np.take_along_axis(node[ok], pick, axis=1))
        seg_faces.append(faces[ok])
    segments = np.concatenate(seg_nodes) if seg_nodes else np.zeros((0, 2), dtype=np.int64)
    seg_face = np.concatenate(seg_faces) if seg_faces else np.zeros(0, dtype=np.int64)
    return Isolines(points=points, edge=owner, t=t, segments=segments, segment_face=seg_face)


@dataclass(frozen=True)
class Polylines:
    """Chains of isoline crossings.

    Attributes
    ----------
    nodes : (K,) crossing indices, polyline after polyline, in order along each.
    offsets : (P + 1,) polyline p is ``nodes[offsets[p]:offsets[p + 1]]``.
    closed : (P,) True for a closed loop (its first node is repeated at its end in ``nodes``).
    link_face : (K,) the face of the link from each node to the next of its polyline (−1 after the last).
    """

    nodes: np.ndarray
    offsets: np.ndarray
    closed: np.ndarray
    link_face: np.ndarray

    @property
    def count(self) -> int:
        return len(self.offsets) - 1


def chain_segments(n_points: int, segments: np.ndarray, segment_face: np.ndarray) -> Polylines:
    """Join segments (S, 2) of crossings into polylines.

    Every crossing lies on at most two segments of a regular pattern; segments at a crossing that
    would join more (a degenerate tie) are left out. Open chains start at their lower-numbered
    end; a closed loop starts at its lowest crossing.
    """
    N = n_points
    a, b = segments[:, 0], segments[:, 1]
    degree = np.bincount(np.concatenate([a, b]), minlength=N)
    branch = degree > 2
    if branch.any():
        # only a phase exactly on a level at a vertex can make a crossing branch: leave such a
        # crossing out, so the isolines through it end there instead of joining wrongly
        keep_seg = ~(branch[a] | branch[b])
        a, b, segment_face = a[keep_seg], b[keep_seg], segment_face[keep_seg]
        degree = np.bincount(np.concatenate([a, b]), minlength=N)
    G = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(N, N)).tocsr()
    n_comp, label = csgraph.connected_components(G, directed=False)
    used = degree > 0
    big = np.iinfo(np.int64).max
    idx = np.arange(N)
    # each component's start: its lowest end if it has ends, else its lowest node (a loop)
    start_end = np.full(n_comp, big)
    np.minimum.at(start_end, label[degree == 1], idx[degree == 1])
    start_any = np.full(n_comp, big)
    np.minimum.at(start_any, label[used], idx[used])
    is_loop = (start_end == big) & (start_any != big)
    start = np.where(is_loop, start_any, start_end)
    comps = np.flatnonzero(start != big)
    start = start[comps]
    loop = is_loop[comps]

    # open each loop: drop one of its start's two links
    sym = (G + G.T).tocsr()
    cut_a = start[loop]
    cut_b = np.zeros(0, dtype=np.int64)
    if cut_a.size:
        first_nb = sym.indices[sym.indptr[cut_a]]      # a loop node has two neighbours
        second_nb = sym.indices[sym.indptr[cut_a] + 1]
        cut_b = np.maximum(first_nb, second_nb)
    keep = np.ones(len(a), dtype=bool)
    if cut_a.size:
        seg_key = np.minimum(a, b) * N + np.maximum(a, b)
        cut_key = np.minimum(cut_a, cut_b) * N + np.maximum(cut_a, cut_b)
        keep = ~np.isin(seg_key, cut_key)
    root = N
    ra = np.concatenate([a[keep], np.full(len(start), root)])
    rb = np.concatenate([b[keep], start])
    T = sp.coo_matrix((np.ones(len(ra)), (ra, rb)), shape=(N + 1, N + 1)).tocsr()
    order, pred = csgraph.depth_first_order(T, root, directed=False, return_predecessors=True)
    order = order[1:]
    begins = np.flatnonzero(pred[order] == root)
    lengths = np.diff(np.append(begins, len(order)))
    # loops repeat their first node at the end
    loop_of_begin = np.isin(order[begins], start[loop])
    counts = lengths + loop_of_begin
    offsets = np.concatenate([[0], np.cumsum(counts)])
    nodes = np.empty(offsets[-1], dtype=np.int64)
    pos = np.arange(len(order)) + np.repeat(offsets[:-1] - begins, lengths)
    nodes[pos] = order
    nodes[offsets[1:][loop_of_begin] - 1] = order[begins[loop_of_begin]]

    face_of = sp.coo_matrix((segment_face + 1.0, (a, b)), shape=(N, N)).tocsr()
    face_of = face_of.maximum(face_of.T).tocsr()
    link_face = np.full(len(nodes), -1, dtype=np.int64)
    has_next = np.ones(len(nodes), dtype=bool)
    has_next[offsets[1:] - 1] = False
    src, dst = nodes[has_next], nodes[np.flatnonzero(has_next) + 1]
    if src.size:                       # scipy answers an empty fancy index with a matrix, not an array
        link_face[has_next] = np.asarray(face_of[src, dst]).ravel().astype(np.int64) - 1
    return Polylines(nodes=nodes, offsets=offsets, closed=loop_of_begin, link_face=link_face)


def integrable_frequency(solver: StripeSolver, direction: np.ndarray, frequency: np.ndarray,
                         spacing_weight: float) -> np.ndarray:
    """The frequency ν' (n,) nearest to ``frequency`` for which the 1-form ν' ⟨X, dx⟩ is closed.

    The stripe energy can follow both the direction X and the frequency ν only where the 1-form
    ω = ν ⟨X, dx⟩ is closed (curl(ν X) = 0); elsewhere KCPS15's eigenvector trades one for the
    other, and isolines leave the direction field. With X fixed, closedness leaves ν free across
    the stripes and fixes how it may change along them (the geometry of the curves decides). This
    finds that ν', in the least-squares sense:

        min_ν'  Σ_f circ_f(ν')² / A_f + β Σ_v m_v ν̄² ((ν'_v − ν_v) / ν_v)²,   β = spacing_weight / area

    circ_f the circulation of ω around face f (with the line field's sign flips; faces where the
    field turns over are left out), m_v the vertex areas, ν̄ the mean frequency. Small β: closed
    (isolines along X, spacing per isoline the best compromise); large β: ν' → ν.

    Parameters
    ----------
    solver : the mesh's stripe solver; direction : (n, 2) X; frequency : (n,) ν > 0.
    spacing_weight : β · area, dimensionless, > 0.
    """
    if not spacing_weight > 0:
        raise ValueError(f"spacing_weight = {spacing_weight}: must be > 0")
    topo = solver.topology
    i, j = topo.edges.T
    flip = np.einsum("ec,ec->e", direction[i], direction[j]) < 0
    s = np.where(flip, -1.0, 1.0)
    a = 0.5 * np.einsum("ec,ec->e", direction[i], solver.edge_vector)         # ω_e = a ν_i + b ν_j
    b = 0.5 * s * np.einsum("ec,ec->e", direction[j], solver.edge_vector)
    fe = topo.face_edges
    sf = s[fe]
    # half-edge k's advance in its tail's orientation is ω (forward) or −s ω; corner k's
    # orientation relative to corner 0 is σ_k
    sigma = np.ones_like(sf)
    sigma[:, 1] = sf[:, 0]
    sigma[:, 2] = sf[:, 0] * sf[:, 1]
    coef = sigma * np.where(topo.forward, 1.0, -sf)                            # (m, 3)
    turned = sf.prod(axis=1) < 0
    area = face_areas(solver.uv, solver.F)
    keep = ~turned & (area > 0)
    rows = np.repeat(np.arange(len(fe)), 3)[np.repeat(keep, 3)]
    ck, ek = coef[keep].ravel(), fe[keep].ravel()
    C = sp.csr_matrix((np.concatenate([ck * a[ek], ck * b[ek]]),
                       (np.concatenate([rows, rows]), np.concatenate([i[ek], j[ek]]))),
                      shape=(len(fe), solver.n))
    nu = np.asarray(frequency, dtype=float)
    beta = spacing_weight / float(area.sum())
    prior = beta * solver.vertex_area * np.mean(nu) ** 2 / nu ** 2
    W = sp.diags(np.where(keep, 1.0 / np.maximum(area, 1e-300), 0.0))
    lhs = (C.T @ W @ C + sp.diags(prior)).tocsc()
    return SymmetricFactor(lhs).solve(prior * nu)
