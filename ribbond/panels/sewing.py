"""The assembled prediction of a target cut into panels (issue 26): the panels released as printed,
placed edge to edge, sewn along their seams, and only then registered onto the whole target.

Each panel is a printed sheet of its own (``release.Sheet``: its flat mesh, the rest forms of its
layout, its stiffness) with its released equilibrium X (``predict.Prediction.sheet`` and
``X_released``, or any ``release.release``). A seam is a list of matched points, mark for mark, on
the flat boundaries of two panels (``SeamPairing``, each panel's own print coordinates); a point is
read on a panel by barycentric interpolation of the vertex positions (``seam_operator``: the sparse
rows B, so a point's position is B X).

**Placement** (``place_panels``; nothing reads the target): panel 0 stays where its release left it;
the others follow breadth-first over the seam graph, each moved by the proper rigid motion (Kabsch)
that best carries its released seam points onto the matched points of the panels already placed.
The fit also pairs, per point, the point lifted by one seam spacing along its face's normal: a seam
lies flat (the tangent planes meet, the fronts on one side), and a straight seam, whose points alone
leave the rotation about it free, is so placed open rather than folded.

**Sewing** (``SewnEnergy``): all panels' positions together minimize

    Σ_k E_k(X_k) + Σ_i (k_i / 2) |(C X)_i|² + Σ_i (kb_i / 2) |(T X)_i|²,     C = [B_a, −B_b] per pair i,

the panels' shell energies at full release (block-diagonal Hessians) plus stiff springs between
matched points (``seam_energy``, quadratic: its Hessian k CᵀC ⊗ I₃ is constant), by the same
Newton as one sheet (``solver.newton``, its stopping rule a property of the equilibrium). The spring
of a point stands for h mm of seam (its spacing): k_i = ``SEAM_STIFFNESS`` × median D_s × h / ℓ,
ℓ the median flat edge length, i.e. 100 times the membrane's own stiffness over a strip of the seam
one element wide, so a seam opens by about a hundredth of the strain that loads it times ℓ (the
gaps after sewing are reported; the tests hold them to a small fraction of a mm).

A seam also keeps the surface going on smoothly (a seam bends at least as stiffly as the cloth
beside it; with springs between points alone the sewn line is a free hinge, and two halves of a
sphere cap met at a crease of 40° on average): per matched pair the sum of the two sides'
derivatives across the seam, T X = ∂X_a/∂ν_a + ∂X_b/∂ν_b (one-sided differences over one edge
length into each panel, ``_across``), is zero where the surface goes on without a kink; its spring
kb_i = ``SEAM_BENDING`` × D_b × h / ℓ (D_b of the two faces at the point) gives a kink θ the energy
of about an interior edge of the shell (whose hinge holds the kink on a fraction of an element, and
|T X| ≈ λθ with the released stretch λ < 1 across). Being quadratic it also asks for equal stretches
across the seam on both sides, but only with the bending's strength (D_b / (D_s ℓ) ≈ 1e-2 of the
membrane's). On the sphere cap's halves the kink's mean over the seam is 8° at a factor of 1, 2.0° at
10, 2.4° at 100.

**Measure**: the sewn positions registered (Kabsch) onto each panel's vertices' target positions,
then each vertex's distance to the whole target, as for one sheet (``compare.surface_deviation``).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..deploy.compare import kabsch, surface_deviation
from ..deploy.predict import Prediction, barycentric
from ..deploy.release import FORCE_TOLERANCE, STEP_TOLERANCE, Sheet
from ..deploy.shell import ShellEnergy
from ..deploy.solver import newton

__all__ = ["SEAM_STIFFNESS", "SEAM_BENDING", "SeamPairing", "ReleasedPanel", "Assembly", "seam_operator", "seam_energy",
           "SewnEnergy", "place_panels", "assemble"]

#: A seam point's spring, × the median membrane stiffness × its spacing / the median edge length.
SEAM_STIFFNESS = 100.0
#: A seam point's bending spring, × the sheet's bending stiffness D_b × its spacing / the edge length
#: (module docstring: about an interior edge's resistance to a kink).
SEAM_BENDING = 10.0
#: A seam point may lie at most this × the panel's median edge length off its flat mesh.
SEAM_OFF_MESH = 1.0


@dataclass(frozen=True)
class SeamPairing:
    """Matched points along one seam, mark for mark.

    Attributes
    ----------
    panel_a, panel_b : the two panels (indices into the panels given to ``assemble``).
    points_a, points_b : (p, 2) the points on each panel's flat boundary, in its own print
        coordinates, mm; point i of a is sewn to point i of b.
    """

    panel_a: int
    points_a: np.ndarray
    panel_b: int
    points_b: np.ndarray


@dataclass(frozen=True)
class ReleasedPanel:
    """A panel as released.

    Attributes
    ----------
    sheet : its printed sheet (flat mesh uv (n, 2), F (m, 3), rest forms, stiffness).
    X : (n, 3) its released equilibrium (any frame: only its shape is used).
    target : (n, 3) its vertices on the whole target: for the registration and the measure only.
    """

    sheet: Sheet
    X: np.ndarray
    target: np.ndarray

    @classmethod
    def from_prediction(cls, prediction: Prediction) -> "ReleasedPanel":
        """The panel of a nominal prediction (``predict_deployed``)."""
        if prediction.sheet is None or prediction.X_released is None:
            raise ValueError("the prediction carries no sheet or released positions")
        return cls(sheet=prediction.sheet, X=prediction.X_released, target=prediction.target)


@dataclass(frozen=True)
class Assembly:
    """The assembled prediction.

    Attributes
    ----------
    V : (N, 3) all panels' vertices, sewn and registered (Kabsch) onto the whole target, mm.
    F : (T, 3) their faces (each panel's, offset by the vertices before it).
    panel : (N,) the panel of each vertex; uv : (N, 2) each vertex in its panel's print coordinates.
    distance : (N,) each vertex's distance to the whole target, mm.
    deviation_pct : {"mean", "p99", "max"} in % of the whole target's bounding-box diagonal.
    seam_gap_mm : {"max", "mean"} distance between matched seam points after sewing, mm.
    placed_gap_mm : {"max", "mean"} the same after the rigid placement, before sewing.
    seam_stiffness : the median spring k_i of a seam point, N/mm.
    iterations : Newton iterations of the sewing; converged : it reached equilibrium.
    time_s : wall time of placement, sewing and measure, s.
    X : (N, 3) the sewn positions before the registration (the placement's frame: panel 0's).
    """

    V: np.ndarray
    F: np.ndarray
    panel: np.ndarray
    uv: np.ndarray
    distance: np.ndarray
    deviation_pct: dict[str, float]
    seam_gap_mm: dict[str, float]
    placed_gap_mm: dict[str, float]
    seam_stiffness: float
    iterations: int
    converged: bool
    time_s: float
    X: np.ndarray = field(repr=False)

    def render_png(self, target_V: np.ndarray, target_F: np.ndarray, title: str = "") -> bytes:
        """The whole target (target_V (n, 3), target_F (m, 3)) beside the assembly coloured by distance."""
        from ..deploy.picture import render_deployed_png
        return render_deployed_png(target_V, target_F, self.V, self.F, self.distance, title=title)

    def report(self) -> dict:
        """The figures as plain JSON values."""
        return {"deviation_pct": dict(self.deviation_pct), "seam_gap_mm": dict(self.seam_gap_mm),
                "placed_gap_mm": dict(self.placed_gap_mm), "seam_stiffness": self.seam_stiffness,
                "iterations": self.iterations, "converged": self.converged, "time_s": self.time_s,
                "panels": int(self.panel.max()) + 1, "faces": len(self.F)}


def seam_operator(points: np.ndarray, uv: np.ndarray, F: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """B (p, n): row i the barycentric weights of point i (p, 2) on the flat mesh (uv (n, 2), F (m, 3)),
    so B X is the points' positions on X (n, 3); the face of each point (p,); each point's distance
    off the mesh (p,), mm (0 inside)."""
    face, c, bary = barycentric(points, uv, F)
    B = sp.csr_matrix((bary.ravel(), (np.repeat(np.arange(len(points)), 3), c.ravel())), shape=(len(points), len(uv)))
    return B, face, np.linalg.norm(B @ uv - points, axis=1)


def seam_energy(X: np.ndarray, C: sp.csr_matrix, k: np.ndarray, derivatives: int = 0):
    """The seams' springs ½ Σ_i k_i |(C X)_i|² (a float) and, up to ``derivatives``, its gradient
    k-weighted Cᵀ C X (3N,) (xyz interleaved) and its constant Hessian Cᵀ diag(k) C ⊗ I₃ (3N, 3N) CSR.

    Parameters
    ----------
    X : (N, 3) positions; C : (q, N) the differences of matched points; k : (q,) springs, N/mm.
    """
    D = C @ X                                                     # (q, 3) gaps
    value = 0.5 * float(np.sum(k[:, None] * D * D))
    if derivatives == 0:
        return value
    grad = (C.T @ (k[:, None] * D)).ravel()
    if derivatives == 1:
        return value, grad
    K = (C.T @ sp.diags(k) @ C).tocsr()
    return value, grad, sp.kron(K, sp.eye(3), format="csr")


class _SumPattern:
    """The fixed sparsity of blocks on the diagonal plus one constant matrix over them, and the maps
    that put each block's data into it (made from the first matrices; their patterns are fixed)."""

    def __init__(self, blocks: list[sp.csc_matrix], offsets: np.ndarray, K: sp.csc_matrix) -> None:
        n = K.shape[0]
        keys = []
        for M, o in zip(blocks + [K], list(offsets) + [0]):
            cols = np.repeat(np.arange(M.shape[1]), np.diff(M.indptr)) + o
            keys.append(cols.astype(np.int64) * n + M.indices + o)
        union = np.unique(np.concatenate(keys))
        self.pos = [np.searchsorted(union, k) for k in keys]
        self.nnz = [M.nnz for M in blocks]
        self.K = K.data.copy()
        self.indices = (union % n).astype(np.int32)
        self.indptr = np.searchsorted(union // n, np.arange(n + 1)).astype(np.int32)
        self.shape = (n, n)

    def assemble(self, blocks: list[sp.csc_matrix]) -> sp.csc_matrix:
        if [M.nnz for M in blocks] != self.nnz:
            raise ValueError("a panel's Hessian changed its sparsity")
        data = np.zeros(len(self.indices))
        for M, p in zip(blocks, self.pos):
            data[p] = M.data                                      # the panels do not overlap
        data[self.pos[-1]] += self.K
        H = sp.csc_matrix((data, self.indices, self.indptr), shape=self.shape)
        H.has_sorted_indices = True
        return H


class SewnEnergy:
    """All panels' shell energies on the stacked positions X (N, 3) plus the seams' springs: the
    interface ``solver.newton`` uses (``energy``, ``gradient``, ``gradient_and_hessians``).

    Parameters
    ----------
    energies : per panel its shell energy (at full release); sizes : its vertex count.
    C : (q, N) the seams' differences of matched points; k : (q,) their springs, N/mm.
    """

    def __init__(self, energies: Sequence[ShellEnergy], sizes: Sequence[int], C: sp.csr_matrix, k: np.ndarray) -> None:
        self.energies = list(energies)
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.n = int(self.offsets[-1])
        if C.shape[1] != self.n or len(k) != C.shape[0]:
            raise ValueError(f"the seam operator must be (q, {self.n}) with q springs, got {C.shape} and {len(k)}")
        self.C, self.k = C.tocsr(), np.asarray(k, dtype=float)
        _, _, self._K = seam_energy(np.zeros((self.n, 3)), self.C, self.k, derivatives=2)
        self._cache: tuple | None = None

    def _panels(self, X: np.ndarray):
        X = np.asarray(X, dtype=float).reshape(-1, 3)
        return [(E, X[a:b]) for E, a, b in zip(self.energies, self.offsets[:-1], self.offsets[1:])]

    def energy(self, X: np.ndarray) -> float:
        """E(X): the panels' energies plus the springs'."""
        return sum(E.energy(Xk) for E, Xk in self._panels(X)) + seam_energy(np.reshape(X, (-1, 3)), self.C, self.k)

    def gradient(self, X: np.ndarray) -> np.ndarray:
        """∇E (3N,), xyz interleaved per vertex."""
        g = np.concatenate([E.gradient(Xk) for E, Xk in self._panels(X)])
        return g + seam_energy(np.reshape(X, (-1, 3)), self.C, self.k, derivatives=1)[1]

    def _pattern(self, free: np.ndarray, lower: bool):
        """Per panel its free dofs (local), and the seams' Hessian on ``free`` (lower triangle with ``lower``)."""
        if self._cache is not None and self._cache[0] == lower and np.array_equal(self._cache[1], free):
            return self._cache[2], self._cache[3]
        local = [free[(free >= 3 * a) & (free < 3 * b)] - 3 * a for a, b in zip(self.offsets[:-1], self.offsets[1:])]
        K = self._K[free][:, free]
        K = (sp.tril(K) if lower else K).tocsc()
        K.sort_indices()
        self._cache = (lower, free.copy(), local, [K, None])
        return local, self._cache[3]

    def gradient_and_hessians(self, X: np.ndarray, free: np.ndarray | None = None, lower: bool = False):
        """(∇E, exact(), psd()) as ``ShellEnergy.gradient_and_hessians``: the gradient (3N,) and two
        functions assembling each Hessian (block-diagonal panels plus the seams' constant one) on
        the rows and columns ``free`` as CSC with sorted indices (the lower triangle with ``lower``)."""
        free = np.arange(3 * self.n) if free is None else np.asarray(free, dtype=np.int64)
        local, seam = self._pattern(free, lower)
        parts = [E.gradient_and_hessians(Xk, fk, lower) for (E, Xk), fk in zip(self._panels(X), local)]
        grad = np.concatenate([p[0] for p in parts])
        grad += seam_energy(np.reshape(X, (-1, 3)), self.C, self.k, derivatives=1)[1]
        offsets = np.concatenate([[0], np.cumsum([len(fk) for fk in local])[:-1]])

        def build(which: int) -> sp.csc_matrix:
            blocks = [p[which]() for p in parts]
            if seam[1] is None:
                seam[1] = _SumPattern(blocks, offsets, seam[0])
            return seam[1].assemble(blocks)

        return grad, (lambda: build(1)), (lambda: build(2))


def _check_inputs(panels: Sequence[ReleasedPanel], seams: Sequence[SeamPairing]) -> None:
    """ValueError naming the panel or seam that is malformed or not connected to panel 0."""
    if not panels:
        raise ValueError("assemble needs at least one panel")
    for i, p in enumerate(panels):
        n = len(p.sheet.uv)
        for name, a in (("X", p.X), ("target", p.target)):
            a = np.asarray(a)
            if a.shape != (n, 3) or not np.all(np.isfinite(a)):
                raise ValueError(f"panel {i}: {name} must be a finite ({n}, 3) array, got shape {a.shape}")
    for j, s in enumerate(seams):
        for side, k in (("panel_a", s.panel_a), ("panel_b", s.panel_b)):
            if not 0 <= k < len(panels):
                raise ValueError(f"seam {j}: {side} = {k} is not a panel (0..{len(panels) - 1})")
        if s.panel_a == s.panel_b:
            raise ValueError(f"seam {j} sews panel {s.panel_a} to itself")
        pa, pb = np.asarray(s.points_a, dtype=float), np.asarray(s.points_b, dtype=float)
        if pa.ndim != 2 or pa.shape[1] != 2 or pa.shape != pb.shape or len(pa) < 2:
            raise ValueError(f"seam {j}: points_a and points_b must be (p, 2) of one shape with p ≥ 2, "
                             f"got {pa.shape} and {pb.shape}")
        if not (np.all(np.isfinite(pa)) and np.all(np.isfinite(pb))):
            raise ValueError(f"seam {j} has non-finite points")
    reached = _breadth_first(len(panels), seams)
    missing = sorted(set(range(len(panels))) - {k for k, _ in reached})
    if missing:
        raise ValueError(f"panel {missing[0]} is not connected to panel 0 by any seam")


def _breadth_first(count: int, seams: Sequence[SeamPairing]) -> list[tuple[int, list[int]]]:
    """Panels in breadth-first order from panel 0, each with the seams joining it to panels before it."""
    order, seen, queue = [], {0}, deque([0])
    while queue:
        k = queue.popleft()
        earlier = {p for p, _ in order}
        order.append((k, [j for j, s in enumerate(seams) if k in (s.panel_a, s.panel_b)
                          and ({s.panel_a, s.panel_b} - {k}) <= earlier]))
        for s in seams:
            if k in (s.panel_a, s.panel_b):
                other = s.panel_b if s.panel_a == k else s.panel_a
                if other not in seen:
                    seen.add(other)
                    queue.append(other)
    return order


def _normals(X: np.ndarray, F: np.ndarray, face: np.ndarray) -> np.ndarray:
    """(p, 3) unit normals of the faces ``face`` (p,) of the mesh (X (n, 3), F)."""
    c = F[face]
    n = np.cross(X[c[:, 1]] - X[c[:, 0]], X[c[:, 2]] - X[c[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


@dataclass(frozen=True)
class _SeamSide:
    """One side of a seam on its panel: B (p, n), the face of each point (p,)."""

    B: sp.csr_matrix
    face: np.ndarray
    across: sp.csr_matrix


def _edge(sheet: Sheet) -> float:
    """The median flat edge length of the sheet, mm."""
    return float(np.median(np.linalg.norm(sheet.uv[sheet.F[:, 1]] - sheet.uv[sheet.F[:, 0]], axis=1)))


def _across(points: np.ndarray, sheet: Sheet, h: float) -> sp.csr_matrix:
    """(p, n): the derivative across the seam into the panel, (X(p + h ν) − X(p)) / h, ν the flat unit
    normal of the seam (p, 2) at each point on the side where the panel is."""
    t = np.gradient(points, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    nu = np.column_stack([-t[:, 1], t[:, 0]])
    B0, _, _ = seam_operator(points, sheet.uv, sheet.F)
    Bp, _, off_p = seam_operator(points + h * nu, sheet.uv, sheet.F)
    Bm, _, off_m = seam_operator(points - h * nu, sheet.uv, sheet.F)
    inside = sp.diags((off_p <= off_m).astype(float))
    return ((inside @ Bp + (sp.eye(len(points)) - inside) @ Bm - B0) / h).tocsr()


def _seam_sides(panels: Sequence[ReleasedPanel], seams: Sequence[SeamPairing]) -> list[tuple[_SeamSide, _SeamSide]]:
    """Per seam, its two sides; ValueError for a point farther off its panel than ``SEAM_OFF_MESH`` edges."""
    out = []
    for j, s in enumerate(seams):
        sides = []
        for k, pts in ((s.panel_a, s.points_a), (s.panel_b, s.points_b)):
            sh = panels[k].sheet
            pts = np.asarray(pts, dtype=float)
            B, face, off = seam_operator(pts, sh.uv, sh.F)
            edge = _edge(sh)
            if off.max() > SEAM_OFF_MESH * edge:
                raise ValueError(f"seam {j}: point {int(off.argmax())} lies {off.max():.3g} mm off panel {k}'s "
                                 f"flat mesh (at most {SEAM_OFF_MESH * edge:.3g} mm: one edge)")
            sides.append(_SeamSide(B=B, face=face, across=_across(pts, sh, edge)))
        out.append((sides[0], sides[1]))
    return out


def _fit_pairs(X: list[np.ndarray], panels: Sequence[ReleasedPanel], sides, k: int, seams: Sequence[SeamPairing],
               joined: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The points of panel k (released) and where they go (the panels placed): the seam points, and
    each lifted by one seam spacing along its face's normal on either side."""
    P, Q = [], []
    for j in joined:
        s, (a, b) = seams[j], sides[j]
        mine, theirs, other = (a, b, s.panel_b) if s.panel_a == k else (b, a, s.panel_a)
        p, q = mine.B @ X[k], theirs.B @ X[other]
        h = float(np.median(np.linalg.norm(np.diff(p, axis=0), axis=1)))
        P += [p, p + h * _normals(X[k], panels[k].sheet.F, mine.face)]
        Q += [q, q + h * _normals(X[other], panels[other].sheet.F, theirs.face)]
    return np.concatenate(P), np.concatenate(Q)


def place_panels(panels: Sequence[ReleasedPanel], seams: Sequence[SeamPairing]) -> list[np.ndarray]:
    """Each panel's released positions moved rigidly into place (module docstring): panel 0 as
    released, each next one (breadth-first) fitted by Kabsch onto the panels placed before it.
    Reads no target. Returns per panel (n_k, 3)."""
    _check_inputs(panels, seams)
    sides = _seam_sides(panels, seams)
    X = [np.asarray(p.X, dtype=float) for p in panels]
    for k, joined in _breadth_first(len(panels), seams)[1:]:
        P, Q = _fit_pairs(X, panels, sides, k, seams, joined)
        R, t = kabsch(P, Q)
        X[k] = X[k] @ R.T + t
    return X


def _springs(panels: Sequence[ReleasedPanel], seams: Sequence[SeamPairing], sides, stiffness: float,
             bending: float) -> tuple[sp.csr_matrix, np.ndarray, sp.csr_matrix, np.ndarray]:
    """The seams' operators on the stacked positions: C (q, N) the difference of each matched pair,
    k (q,) its springs, N/mm; T (q, N) the sum of the two sides' derivatives across the seam (zero where
    the surface goes on smoothly), kb (q,) its bending springs, N·mm (module docstring)."""
    sizes = [len(p.sheet.uv) for p in panels]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    n = int(offsets[-1])
    ds = np.median(np.concatenate([p.sheet.stretch for p in panels]))
    edge = np.median([_edge(p.sheet) for p in panels])
    C, k, T, kb = [], [], [], []
    for s, (a, b) in zip(seams, sides):
        C.append(_columns(a.B, offsets[s.panel_a], n) - _columns(b.B, offsets[s.panel_b], n))
        T.append(_columns(a.across, offsets[s.panel_a], n) + _columns(b.across, offsets[s.panel_b], n))
        h = 0.5 * (_spacing(np.asarray(s.points_a, dtype=float)) + _spacing(np.asarray(s.points_b, dtype=float)))
        k.append(stiffness * ds * h / edge)
        db = 0.5 * (panels[s.panel_a].sheet.bend[a.face] + panels[s.panel_b].sheet.bend[b.face])
        kb.append(bending * db * h / (0.5 * (_edge(panels[s.panel_a].sheet) + _edge(panels[s.panel_b].sheet))))
    return sp.vstack(C).tocsr(), np.concatenate(k), sp.vstack(T).tocsr(), np.concatenate(kb)


def _columns(B: sp.csr_matrix, offset: int, n: int) -> sp.csr_matrix:
    """B (p, n_k) as the rows of a (p, n) operator on the stacked positions, its columns from ``offset``."""
    B = B.tocoo()
    return sp.csr_matrix((B.data, (B.row, B.col + offset)), shape=(B.shape[0], n))


def _spacing(points: np.ndarray) -> np.ndarray:
    """(p,) the seam length each point stands for: half its two neighbouring intervals (flat, mm)."""
    d = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return 0.5 * (np.concatenate([[0.0], d]) + np.concatenate([d, [0.0]]))


def _gaps(C: sp.csr_matrix, X: np.ndarray) -> dict[str, float]:
    g = np.linalg.norm(C @ X, axis=1)
    return {"max": float(g.max()), "mean": float(g.mean())}


def assemble(panels: Sequence[ReleasedPanel], seams: Sequence[SeamPairing], target_V: np.ndarray,
             target_F: np.ndarray, *, stiffness: float = SEAM_STIFFNESS, bending: float = SEAM_BENDING,
             max_iterations: int = 200,
             progress: Callable[[int, float, float], None] | None = None) -> Assembly:
    """Place the released panels, sew them along their seams, register and measure the whole.

    Parameters
    ----------
    panels : the released panels (``ReleasedPanel.from_prediction`` of each panel's prediction).
    seams : the matched points of every seam; every panel must be reached from panel 0.
    target_V : (n, 3), target_F : (m, 3) the whole target: registers and measures the result only.
    stiffness : ``SEAM_STIFFNESS``; bending : ``SEAM_BENDING`` (0: the seams are free hinges).
    max_iterations : Newton's cap for the sewing.
    progress : Newton's (iteration, energy, ‖∇E‖∞) after each iteration.

    Returns
    -------
    Assembly.

    Raises
    ------
    ValueError
        for a malformed panel or seam (named), a seam point off its panel, a panel no seam reaches.
    """
    t0 = time.perf_counter()
    if not stiffness > 0:
        raise ValueError(f"stiffness must be > 0, got {stiffness!r}")
    X0 = np.concatenate(place_panels(panels, seams))
    sides = _seam_sides(panels, seams)
    C, k, T, kb = _springs(panels, seams, sides, stiffness, bending)
    energy = SewnEnergy([p.sheet.energy_at(1.0) for p in panels], [len(p.sheet.uv) for p in panels],
                        sp.vstack([C, T]).tocsr(), np.concatenate([k, kb]))
    force = min(p.sheet.force_scale for p in panels)
    scale = float(np.linalg.norm(X0.max(axis=0) - X0.min(axis=0)))
    r = newton(energy, X0, max_iterations=max_iterations, step_tolerance=STEP_TOLERANCE, scale=scale,
               gradient_tolerance=FORCE_TOLERANCE * force, progress=progress)
    offsets = np.concatenate([[0], np.cumsum([len(p.sheet.uv) for p in panels])])
    F = np.concatenate([p.sheet.F + o for p, o in zip(panels, offsets[:-1])])
    dev = surface_deviation(r.X, np.concatenate([np.asarray(p.target, dtype=float) for p in panels]),
                            target_V, target_F)
    return Assembly(V=dev.V, F=F, panel=np.repeat(np.arange(len(panels)), np.diff(offsets)),
                    uv=np.concatenate([p.sheet.uv for p in panels]), distance=dev.distance,
                    deviation_pct=dev.as_dict(), seam_gap_mm=_gaps(C, r.X), placed_gap_mm=_gaps(C, X0),
                    seam_stiffness=float(np.median(k)), iterations=r.iterations, converged=r.converged,
                    time_s=time.perf_counter() - t0, X=r.X)
