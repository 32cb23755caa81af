"""A discrete thin shell in fundamental-form form (Chen et al. 2018, libshell's formulation).

The reference domain is the flat (pre-stretched) mesh; each face f carries a rest first
fundamental form ā and a rest second fundamental form b̄ (``rest_forms.py``), both 2 × 2 in the
basis of the face's two flat edge vectors (ū1 = p̄1 − p̄0, ū2 = p̄2 − p̄0), so a_ij = e_i · e_j with
e1 = x1 − x0, e2 = x2 − x0 the deformed edges. The energy is Chen et al.'s Eq. (4)/(5):

    E = Σ_f  A_f/(1 − ν²) · [ D_s/8 · Φ(ā⁻¹a − I)  +  D_b/2 · Φ(ā⁻¹(b − b̄)) ],
    Φ(M) = ν tr(M)² + (1 − ν) tr(M²),

A_f the rest area (½ √det ā), D_s = Σ Y h the membrane and D_b = Σ Y h³/12 the bending stiffness
of the face (St.Venant–Kirchhoff on the 2D metric, plane stress).

Second fundamental form: the mid-edge shape operator (Chen et al. §4; libshell's
``MidedgeAverageFormulation``). The mid-edge normal of edge i (opposite vertex i) is
m_i = cos φ_i n + sin φ_i t_i (t_i the outward in-plane normal of the edge, φ_i half the dihedral
angle, > 0 where the surface bulges toward +n); n is linear on the face through the three mid-edge
values, which gives, with h_i the height of vertex i over edge i,

    b = 2 [ s0 h0 [[1, 1], [1, 1]] + s1 h1 [[1, 0], [0, 0]] + s2 h2 [[0, 0], [0, 1]] ],

here with s_i = tan(θ_i / 2) (θ_i the signed dihedral angle; = φ_i to first order, smooth at 0) and the
heights h_i taken in the rest metric ā (the in-plane weights at rest, as Grinspun et al.'s discrete
shells take rest lengths and areas). The sign follows design-format.md: b > 0 where the surface
bulges toward the face normal n of the winding. With the heights at rest, b is linear in the edge
vector s, and the bending energy is a fixed quadratic in s, assembled once:

    E_b(x) = ½ s(x)ᵀ H s(x) + gᵀ s(x) + c.

Boundary edges have no dihedral angle: their mid-edge normal is a free variable (Chen et al.'s
edge degrees of freedom), eliminated here in closed form per face (a Schur complement), so a free
boundary bends without resistance of its own.

Every term has its analytic gradient and Hessian next to it, vectorized over faces or edges;
``tests/deploy/test_shell.py`` checks each against finite differences.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["ShellTopology", "shell_topology", "hinge_tan", "stretch_energy", "BendingQuadratic",
           "bending_quadratic", "ShellEnergy", "quadratic_form", "edge_basis_forms"]


# -- small vectorized helpers ------------------------------------------------------------------------

def _outer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, :, None] * b[:, None, :]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ki,ki->k", a, b)


def quadratic_form(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Q (k, 3, 3) and l (k, 3) such that for symmetric X with X_vec = (x11, x12, x22):
    tr(P X P X) = X_vecᵀ Q X_vec and tr(P X) = l · X_vec.

    Parameters
    ----------
    P : (k, 2, 2) symmetric matrices (here ā⁻¹).
    """
    p, q, r = P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]
    Q = np.stack([np.stack([p * p, 2 * p * q, q * q], -1),
                  np.stack([2 * p * q, 2 * q * q + 2 * p * r, 2 * q * r], -1),
                  np.stack([q * q, 2 * q * r, r * r], -1)], 1)
    return Q, np.stack([p, 2 * q, r], -1)


def edge_basis_forms(uv: np.ndarray, F: np.ndarray, A_cart: np.ndarray) -> np.ndarray:
    """A symmetric 2-tensor given in flat Cartesian coordinates, in each face's edge basis.

    Parameters
    ----------
    uv : (n, 2) flat positions; F : (m, 3) faces; A_cart : (m, 2, 2) the tensor per face.

    Returns
    -------
    (m, 3) (X11, X12, X22) with X_ij = ū_iᵀ A ū_j, ū1 = p̄1 − p̄0, ū2 = p̄2 − p̄0.
    """
    u1 = uv[F[:, 1]] - uv[F[:, 0]]
    u2 = uv[F[:, 2]] - uv[F[:, 0]]
    return np.stack([np.einsum("ki,kij,kj->k", u1, A_cart, u1),
                     np.einsum("ki,kij,kj->k", u1, A_cart, u2),
                     np.einsum("ki,kij,kj->k", u2, A_cart, u2)], -1)


# -- topology -----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ShellTopology:
    """Edges and hinges of a triangle mesh.

    Attributes
    ----------
    F : (m, 3) faces.
    face_edge : (m, 3) index of the edge opposite vertex i of each face.
    hinge : (h, 4) interior edges as hinges (v0, v1, v2, v3): face f0 = (v0, v1, v2) counter-clockwise
        (so the shared edge runs v1 -> v2 in f0), v3 the opposite vertex of the other face.
    hinge_edge : (h,) the edge index of each hinge.
    boundary_edge : (E,) bool, the edge has one face.
    n_edges : E.
    """

    F: np.ndarray
    face_edge: np.ndarray
    hinge: np.ndarray
    hinge_edge: np.ndarray
    boundary_edge: np.ndarray
    n_edges: int


def shell_topology(F: np.ndarray) -> ShellTopology:
    """Edges, hinges and the face-edge incidence of a consistently oriented manifold mesh F (m, 3)."""
    F = np.asarray(F, dtype=np.int64)
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise ValueError(f"faces must have shape (m, 3) with m ≥ 1, got {F.shape}")
    m = len(F)
    # half-edge (a, b) of face f opposite local vertex i: a = F[f, i+1], b = F[f, i+2]
    a = np.concatenate([F[:, 1], F[:, 2], F[:, 0]])
    b = np.concatenate([F[:, 2], F[:, 0], F[:, 1]])
    opp = np.concatenate([F[:, 0], F[:, 1], F[:, 2]])
    face = np.tile(np.arange(m), 3)
    local = np.repeat(np.arange(3), m)
    key = np.minimum(a, b) * (F.max() + 1) + np.maximum(a, b)
    uniq, edge, counts = np.unique(key, return_inverse=True, return_counts=True)
    if counts.max() > 2:
        raise ValueError("the mesh has an edge shared by more than two faces: a shell needs a manifold mesh")
    face_edge = np.empty((m, 3), dtype=np.int64)
    face_edge[face, local] = edge
    order = np.argsort(edge, kind="stable")
    e_sorted = edge[order]
    first = np.r_[True, e_sorted[1:] != e_sorted[:-1]]
    starts = np.flatnonzero(first)
    two = counts[e_sorted[starts]] == 2
    h0 = order[starts[two]]          # half-edge in f0
    h1 = order[starts[two] + 1]      # half-edge in the other face
    if np.any(a[h0] != b[h1]):
        raise ValueError("the faces are not consistently oriented (an interior edge runs the same way in "
                         "both its faces)")
    hinge = np.column_stack([opp[h0], a[h0], b[h0], opp[h1]])
    boundary = counts == 1
    return ShellTopology(F=F, face_edge=face_edge, hinge=hinge, hinge_edge=edge[h0],
                         boundary_edge=boundary, n_edges=len(uniq))


# -- the hinge quantity s = tan(θ/2) ---------------------------------------------------------------
#
# The hinges' arrays are kept batch-last, (3, h) vectors and (3, 3, h) matrices: numpy's inner loop
# then runs over the h hinges, not over a trailing axis of 3 (10× fewer loop overheads).

def _cross3(a: np.ndarray, b: np.ndarray, axis: int = 0) -> np.ndarray:
    """a × b over the component axis ``axis`` (0 or 1) of a (3, ...) or (k, 3, ...); b (3, h)
    broadcast over a's other axes (a's trailing axis is h)."""
    out = np.empty(a.shape)
    part = (lambda x, i: x[i]) if axis == 0 else (lambda x, i: x[:, i])
    t = np.empty(part(a, 0).shape)
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        o = part(out, i)
        np.multiply(part(a, j), b[k], out=o)
        np.multiply(part(a, k), b[j], out=t)
        np.subtract(o, t, out=o)
    return out


def _skew3(a: np.ndarray) -> np.ndarray:
    """[a]× (3, 3, h), [a]× w = a × w, of a batch-last vector a (3, h)."""
    z = np.zeros_like(a[0])
    return np.stack([np.stack([z, -a[2], a[1]]), np.stack([a[2], z, -a[0]]), np.stack([-a[1], a[0], z])])


def _projector3(a: np.ndarray) -> np.ndarray:
    """I − a aᵀ (3, 3, h) of batch-last unit vectors a (3, h)."""
    return np.eye(3)[:, :, None] - a[:, None, :] * a[None, :, :]


def _skew_scatter(blocks: tuple[tuple[int, int, int, int], ...], width: int) -> tuple[np.ndarray, ...]:
    """Where the off-diagonal entries of cross-matrix blocks go in a flattened (·, width) matrix.

    blocks : (row block, column block, source vector, sign) per block, the block being
        sign × [source]× at rows 3·row block, columns 3·column block.

    Returns
    -------
    positions (6b,) into the flattened matrix, sources (6b,) into the sources' flattened (k, 3)
    components, signs (6b,).
    """
    entries = ((0, 1, 2, -1.0), (0, 2, 1, 1.0), (1, 0, 2, 1.0), (1, 2, 0, -1.0), (2, 0, 1, -1.0), (2, 1, 0, 1.0))
    pos, src, sign = [], [], []
    for rb, cb, k, sg in blocks:
        for i, j, comp, s in entries:
            pos.append((3 * rb + i) * width + 3 * cb + j)
            src.append(3 * k + comp)
            sign.append(sg * s)
    return np.array(pos), np.array(src), np.array(sign)


#: The second derivatives of N_f (v0, v1, v2) and N_g (v2, v1, v3) contracted with ∂s/∂N_f, ∂s/∂N_g:
#: cross-matrix blocks of ∂s/∂N_f (source 0), ∂s/∂N_g (1) and their difference (2) in ∂²s/∂x² (12, 12).
_N2_POS, _N2_SRC, _N2_SIGN = _skew_scatter(tuple(
    t for i, j, k, sg in ((0, 1, 0, -1.0), (0, 2, 0, 1.0), (1, 2, 2, 1.0), (2, 3, 1, 1.0), (1, 3, 1, -1.0))
    for t in ((i, j, k, sg), (j, i, k, -sg))), 12)


def hinge_tan(X: np.ndarray, hinge: np.ndarray, derivatives: int = 0
              ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """s = tan(θ/2) of each hinge, θ the signed dihedral angle (> 0 where the surface bulges toward +n).

    With N_f = (v1 − v0) × (v2 − v0), N_g = (v1 − v2) × (v3 − v2) and e = v2 − v1,
    tan(θ/2) = sin θ / (1 + cos θ) = (N_f × N_g)·e / (|e| (|N_f||N_g| + N_f·N_g)).

    Parameters
    ----------
    X : (n, 3) positions; hinge : (h, 4) from ``shell_topology``.
    derivatives : 0 value only, 1 with the gradient, 2 with the gradient and Hessian.

    Returns
    -------
    s (h,), gradient (h, 12) or None, Hessian (h, 12, 12) or None, over (v0, v1, v2, v3) xyz.
    """
    hg = _HingeGeometry(X, hinge)
    if derivatives == 0:
        return hg.s, None, None
    grad = hg.gradient()
    return hg.s, grad, (np.ascontiguousarray(hg.hessian().transpose(2, 0, 1)) if derivatives == 2 else None)


class _HingeGeometry:
    """The hinges' shared quantities at one X, so that the gradient and (on demand, later in the same
    Newton iteration) the Hessian reuse them instead of recomputing from X. Batch-last: (3, h)."""

    def __init__(self, X: np.ndarray, hinge: np.ndarray) -> None:
        XT = np.ascontiguousarray(np.asarray(X, dtype=float).T)
        v0, v1, v2, v3 = (XT[:, hinge[:, k]] for k in range(4))
        self._v = (v0, v1, v2, v3)
        self.Nf = _cross3(v1 - v0, v2 - v0)
        self.Ng = _cross3(v1 - v2, v3 - v2)
        self.e = v2 - v1
        self.nf = np.sqrt((self.Nf * self.Nf).sum(0))
        self.ng = np.sqrt((self.Ng * self.Ng).sum(0))
        self.L = np.sqrt((self.e * self.e).sum(0))
        P = (_cross3(self.Nf, self.Ng) * self.e).sum(0)
        self.Qv = self.nf * self.ng + (self.Nf * self.Ng).sum(0)
        self.D = self.L * self.Qv
        self.s = P / self.D
        self._grad: np.ndarray | None = None

    def _pull(self, gf: np.ndarray, gg: np.ndarray, ge: np.ndarray) -> np.ndarray:
        """uᵀ-gradient (∂/∂N_f, ∂/∂N_g, ∂/∂e) (3, h) each pulled back to (v0, v1, v2, v3) (h, 12):
        λᵀ[w]× = (λ × w)ᵀ."""
        w = self.w
        c = [_cross3(gf, w[k]) for k in range(3)] + [_cross3(gg, w[k]) for k in range(3, 6)]
        out = np.stack([c[0], c[1] + c[4] - ge, c[2] + c[3] + ge, c[5]])          # (4, 3, h)
        return np.ascontiguousarray(out.reshape(12, -1).T)

    def gradient(self) -> np.ndarray:
        """∂s/∂x (h, 12)."""
        if self._grad is not None:
            return self._grad
        v0, v1, v2, v3 = self._v
        # the arguments of J = ∂u/∂x's cross-matrix blocks (signs folded in: −[a]× = [−a]×): N_f's at
        # v0, v1, v2, N_g's at v2, v1, v3
        self.w = np.stack([v2 - v1, v0 - v2, v1 - v0, v3 - v1, v2 - v3, v1 - v2])      # (6, 3, h)
        Nf, Ng, e, D = self.Nf, self.Ng, self.e, self.D
        self.Nfh, self.Ngh, self.eh = Nf / self.nf, Ng / self.ng, e / self.L
        self.gQf = self.ng * self.Nfh + Ng
        self.gQg = self.nf * self.Ngh + Nf
        # ∂s/∂u = ∂P/∂u / D − s/D ∂D/∂u, ∂D/∂u = Q ∂L/∂u + L ∂Q/∂u
        sD = self.s / D
        LsD = sD * self.L
        self.gT = (_cross3(Ng, e) / D - LsD * self.gQf,
                   _cross3(e, Nf) / D - LsD * self.gQg,
                   _cross3(Nf, Ng) / D - (sD * self.Qv) * self.eh)
        self._grad = self._pull(*self.gT)
        return self._grad

    def _u_hessian(self, weight: np.ndarray | None) -> np.ndarray:
        """weight × ∂²s/∂u² (9, 9, h) (notation of ``hessian``; the weight folded into the
        coefficients, not a pass over M)."""
        D, L, Qv, nf, ng = self.D, self.L, self.Qv, self.nf, self.ng
        wt = 1.0 if weight is None else weight
        c = self.s / D
        cL = c * L * wt
        C = [_skew3(a * (wt / D)) for a in (self.e, self.Nf, self.Ng)]
        M = np.empty((9, 9, len(D)))
        M[0:3, 0:3] = -(cL * (ng / nf)) * _projector3(self.Nfh)
        M[3:6, 3:6] = -(cL * (nf / ng)) * _projector3(self.Ngh)
        M[0:3, 3:6] = -C[0] - cL * (self.Nfh[:, None] * self.Ngh[None, :] + np.eye(3)[:, :, None])
        M[3:6, 0:3] = M[0:3, 3:6].transpose(1, 0, 2)
        M[0:3, 6:9] = C[2]
        M[6:9, 0:3] = -C[2]
        M[3:6, 6:9] = -C[1]
        M[6:9, 3:6] = C[1]
        M[6:9, 6:9] = -(c * Qv / L * wt) * _projector3(self.eh)
        # the rank-two parts: R = [∂s, ∂L]ᵀ [b, c ∂Q], M −= R + Rᵀ
        U0 = np.concatenate(self.gT) * wt
        V0 = np.concatenate([(L / D) * self.gQf, (L / D) * self.gQg, (Qv / D) * self.eh])
        V1 = np.concatenate([c * self.gQf, c * self.gQg])
        R = U0[:, None] * V0[None, :]
        R[6:9, 0:6] += (self.eh * wt)[:, None] * V1[None, :]
        M -= R
        M -= R.transpose(1, 0, 2)
        return M

    def hessian(self, weight: np.ndarray | None = None) -> np.ndarray:
        """∂²s/∂x² (12, 12, h), batch-last, times ``weight`` (h,) if given. With b = ∂D/∂u / D and
        c = s/D, ∂²s/∂u² = ∂²P/D − c (Q ∂²L + L ∂²Q) − (∂s bᵀ + b ∂sᵀ) − c (∂L ∂Qᵀ + ∂Q ∂Lᵀ) (the
        terms in s/D² and 2s/D³ of the quotient rule cancel), pulled back as Jᵀ M J, plus the second
        derivatives of N_f, N_g contracted with ∂s/∂N.

        J's blocks are [w_k]× (N_f, N_g) and ∓I (e): A [w]× and [w]×ᵀ B are cross products of A's
        rows and B's columns with w, so no 9 × 12 J is formed; the blocks below the diagonal are
        the transposes of those above (the result is exactly symmetric)."""
        if self._grad is None:
            self.gradient()
        M = self._u_hessian(weight)
        w = self.w
        Mf, Mg, Me = M[:, 0:3], M[:, 3:6], M[:, 6:9]                                # (9, 3, h)
        T = np.concatenate([_cross3(Mf, w[0], axis=1),
                            _cross3(Mf, w[1], axis=1) + _cross3(Mg, w[4], axis=1) - Me,
                            _cross3(Mf, w[2], axis=1) + _cross3(Mg, w[3], axis=1) + Me,
                            _cross3(Mg, w[5], axis=1)], axis=1)                     # M J (9, 12, h)
        Tf, Tg, Te = T[0:3], T[3:6], T[6:9]                                         # (3, 12, h)
        hess = np.empty((12, 12, len(self.s)))                                      # Jᵀ M J
        hess[0:3] = _cross3(Tf, w[0])
        hess[3:6, 3:] = _cross3(Tf[:, 3:], w[1]) + _cross3(Tg[:, 3:], w[4]) - Te[:, 3:]
        hess[6:9, 6:] = _cross3(Tf[:, 6:], w[2]) + _cross3(Tg[:, 6:], w[3]) + Te[:, 6:]
        hess[9:12, 9:] = _cross3(Tg[:, 9:], w[5])
        for i in range(1, 4):
            for j in range(i):
                hess[3 * i:3 * i + 3, 3 * j:3 * j + 3] = hess[3 * j:3 * j + 3, 3 * i:3 * i + 3].transpose(1, 0, 2)
        gf, gg = self.gT[0], self.gT[1]
        if weight is not None:
            gf, gg = weight * gf, weight * gg
        G = np.concatenate([gf, gg, gg - gf])                                       # (9, h)
        hess.reshape(144, -1)[_N2_POS] += G[_N2_SRC] * _N2_SIGN[:, None]
        return hess


# -- stretching -------------------------------------------------------------------------------------

def stretch_energy(X: np.ndarray, F: np.ndarray, abar: np.ndarray, coef: np.ndarray, nu: float,
                   derivatives: int = 0, forms: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """St.Venant–Kirchhoff membrane energy per face, c [(1 − ν) tr(M²) + ν tr(M)²], M = ā⁻¹a − I.

    Parameters
    ----------
    X : (n, 3) positions; F : (m, 3) faces.
    abar : (m, 3) rest first fundamental form (ā11, ā12, ā22) in the edge basis.
    coef : (m,) c = A D_s / (8 (1 − ν²)).
    nu : Poisson's ratio.
    derivatives : 0, 1 or 2 (3: the Hessian's two parts, Jᵀ∇²W J (m, 6, 6) and ∇W (m, 3)).
    forms : ``quadratic_form(ā⁻¹)`` if made already (it depends on ā only).

    Returns
    -------
    W (m,), gradient (m, 9) over (x0, x1, x2) or None, Hessian (m, 6, 6) in (e1, e2) or None
    (``E_TO_X`` maps it to (x0, x1, x2)).
    """
    x0, x1, x2 = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    e1, e2 = x1 - x0, x2 - x0
    a = np.stack([_dot(e1, e1), _dot(e1, e2), _dot(e2, e2)], -1)
    Q, l = forms if forms is not None else quadratic_form(_inverse_2x2(abar))
    tr = _dot(l, a) - 2.0
    tr2 = np.einsum("ki,kij,kj->k", a, Q, a) - 2 * _dot(l, a) + 2.0
    W = coef * ((1 - nu) * tr2 + nu * tr ** 2)
    if derivatives == 0:
        return W, None, None
    Wa = coef[:, None] * ((1 - nu) * (2 * np.einsum("kij,kj->ki", Q, a) - 2 * l) + 2 * nu * tr[:, None] * l)
    ge1 = 2 * Wa[:, 0:1] * e1 + Wa[:, 1:2] * e2
    ge2 = Wa[:, 1:2] * e1 + 2 * Wa[:, 2:3] * e2
    grad = np.concatenate([-(ge1 + ge2), ge1, ge2], 1)
    if derivatives == 1:
        return W, grad, None
    m = len(F)
    Waa = coef[:, None, None] * (2 * (1 - nu) * Q + 2 * nu * _outer(l, l))
    Ja = np.zeros((m, 3, 6))
    Ja[:, 0, 0:3] = 2 * e1
    Ja[:, 1, 0:3], Ja[:, 1, 3:6] = e2, e1
    Ja[:, 2, 3:6] = 2 * e2
    GN = np.swapaxes(Ja, 1, 2) @ Waa @ Ja
    if derivatives == 3:
        return W, grad, (GN, Wa)
    He = GN + _stress_term(Wa)
    return W, grad, He   # Hessian in (e1, e2): callers map it to (x0, x1, x2) with E_TO_X


#: (6, 9) the map from (x0, x1, x2) to (e1, e2) = (x1 − x0, x2 − x0).
E_TO_X = np.hstack([np.vstack([-np.eye(3), -np.eye(3)]), np.vstack([np.eye(3), np.zeros((3, 3))]),
                    np.vstack([np.zeros((3, 3)), np.eye(3)])])


def _inverse_2x2(A: np.ndarray) -> np.ndarray:
    """(k, 2, 2) inverses of symmetric forms given as (k, 3) (x11, x12, x22)."""
    det = A[:, 0] * A[:, 2] - A[:, 1] ** 2
    if np.any(det <= 0):
        bad = int(np.flatnonzero(det <= 0)[0])
        raise ValueError(f"the rest metric of face {bad} is not positive definite (det = {det[bad]:.3g})")
    inv = np.empty((len(A), 2, 2))
    inv[:, 0, 0] = A[:, 2] / det
    inv[:, 1, 1] = A[:, 0] / det
    inv[:, 0, 1] = inv[:, 1, 0] = -A[:, 1] / det
    return inv


# -- bending: a fixed quadratic in the edge values s ---------------------------------------------------

@dataclass(frozen=True)
class BendingQuadratic:
    """E_b = ½ sᵀ H s + g · s + c over the edge values s (E,) (boundary entries unused, zero).

    Attributes
    ----------
    H : (E, E) sparse symmetric positive semidefinite; g : (E,); c : float.
    """

    H: sp.csr_matrix
    g: np.ndarray
    c: float
    face_H: np.ndarray | None = None     # (m, 3, 3) per face over its edges (H = Σ_f scatter(face_H))
    face_g: np.ndarray | None = None     # (m, 3) per face over its edges (g = Σ_f scatter(face_g))
    face_G: np.ndarray | None = None     # (m, 3, 3) ∂face_g/∂b̄_f (face_g = face_G b̄_f: g is linear in b̄)

    def value(self, s: np.ndarray) -> float:
        return float(0.5 * s @ (self.H @ s) + self.g @ s + self.c)


def bending_quadratic(topo: ShellTopology, abar: np.ndarray, bbar: np.ndarray, coef: np.ndarray,
                      nu: float) -> BendingQuadratic:
    """Assemble Σ_f c_f [(1 − ν) tr(N²) + ν tr(N)²], N = ā⁻¹(b − b̄), as a quadratic in the edge values.

    b_vec = C s_f with C's columns 2 h0 (1, 1, 1), 2 h1 (1, 0, 0), 2 h2 (0, 0, 1) (module docstring),
    h_i = √det ā / ℓ_i the rest heights (ℓ0² = ā11 − 2ā12 + ā22, ℓ1² = ā22, ℓ2² = ā11). Boundary
    edges' values are minimized out per face (Schur complement): H_eff = H − H Z (Z H Z + I − Z)⁻¹ Z H.

    Parameters
    ----------
    topo : the mesh topology; abar, bbar : (m, 3) rest forms in the edge basis;
    coef : (m,) c = A D_b / (2 (1 − ν²)); nu : Poisson's ratio.
    """
    m = len(topo.F)
    P = _inverse_2x2(abar)
    Q, l = quadratic_form(P)
    K = coef[:, None, None] * ((1 - nu) * Q + nu * _outer(l, l))          # W = dᵀ K d
    sq = np.sqrt(abar[:, 0] * abar[:, 2] - abar[:, 1] ** 2)
    ell = np.sqrt(np.stack([abar[:, 0] - 2 * abar[:, 1] + abar[:, 2], abar[:, 2], abar[:, 0]], -1))
    hgt = sq[:, None] / ell                                                # (m, 3)
    C = np.zeros((m, 3, 3))
    C[:, :, 0] = 2 * hgt[:, 0:1]
    C[:, 0, 1] = 2 * hgt[:, 1]
    C[:, 2, 2] = 2 * hgt[:, 2]
    H = 2 * np.swapaxes(C, 1, 2) @ K @ C
    G = -2 * np.swapaxes(C, 1, 2) @ K                                      # g = G b̄ per face
    g = np.einsum("kij,kj->ki", G, bbar)
    c = np.einsum("ka,kab,kb->k", bbar, K, bbar)
    free = topo.boundary_edge[topo.face_edge].astype(float)               # (m, 3)
    if free.any():
        Z = free[:, :, None] * np.eye(3)
        Mz = Z @ H @ Z + (np.eye(3) - Z)
        S = Z @ np.linalg.inv(Mz) @ Z                                      # (m, 3, 3)
        HS = H @ S
        c = c - 0.5 * np.einsum("ki,kij,kj->k", g, S, g)
        g = g - np.einsum("kij,kj->ki", HS, g)
        G = G - HS @ G
        H = H - HS @ H
        H = 0.5 * (H + np.swapaxes(H, 1, 2))
        keep = 1.0 - free                                                  # boundary entries: no s
        H = H * keep[:, :, None] * keep[:, None, :]
        g = g * keep
        G = G * keep[:, :, None]
    fe = topo.face_edge
    rows = np.repeat(fe, 3, axis=1).ravel()
    cols = np.tile(fe, (1, 3)).ravel()
    Hs = sp.csr_matrix((H.ravel(), (rows, cols)), shape=(topo.n_edges, topo.n_edges))
    gs = np.bincount(fe.ravel(), weights=g.ravel(), minlength=topo.n_edges)
    return BendingQuadratic(H=Hs, g=gs, c=float(c.sum()), face_H=H, face_g=g, face_G=G)


# -- the whole energy ---------------------------------------------------------------------------------

def _project_psd(H: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """Per-element projection of symmetric (k, d, d) matrices onto the positive semidefinite cone."""
    w, U = np.linalg.eigh(H)
    return (U * np.maximum(w, floor)[:, None, :]) @ np.swapaxes(U, 1, 2)


class ShellEnergy:
    """The shell energy of positions X (n, 3) with its analytic gradient and (projected) Hessian.

    Parameters
    ----------
    F : (m, 3) faces (counter-clockwise in the reference domain).
    abar, bbar : (m, 3) rest fundamental forms in the edge basis (``edge_basis_forms``).
    stretch_coef : (m,) A D_s / (8 (1 − ν²)); bend_coef : (m,) A D_b / (2 (1 − ν²)).
    nu : Poisson's ratio.
    """

    def __init__(self, F: np.ndarray, abar: np.ndarray, bbar: np.ndarray, stretch_coef: np.ndarray,
                 bend_coef: np.ndarray, nu: float) -> None:
        self.topo = shell_topology(F)
        self.F = self.topo.F
        self.n = int(self.F.max()) + 1
        self.abar = np.asarray(abar, dtype=float)
        self.stretch_coef = np.asarray(stretch_coef, dtype=float)
        self._stretch_forms = quadratic_form(_inverse_2x2(self.abar))      # fixed: once, not per call
        self._last_hinges: tuple[np.ndarray, _HingeGeometry] | None = None  # (X, its hinges): ``_hinges``
        self.nu = float(nu)
        self._bend_coef = np.asarray(bend_coef, dtype=float)
        self.bending = bending_quadratic(self.topo, self.abar, np.asarray(bbar, dtype=float),
                                         self._bend_coef, self.nu)
        dof = 3 * self.F[:, :, None] + np.arange(3)                        # (m, 3, 3)
        self._fdof = dof.reshape(-1, 9)
        hd = 3 * self.topo.hinge[:, :, None] + np.arange(3)
        self._hdof = hd.reshape(-1, 12)
        self._hedge = self.topo.hinge_edge
        self._face_neighbourhoods()

    def _edge_values(self, s_h: np.ndarray) -> np.ndarray:
        s = np.zeros(self.topo.n_edges)
        s[self._hedge] = s_h
        return s

    def energy(self, X: np.ndarray) -> float:
        """E(X) (a float): stretching plus bending."""
        W, _, _ = stretch_energy(X, self.F, self.abar, self.stretch_coef, self.nu, forms=self._stretch_forms)
        hinges = self._hinges(X)
        return float(W.sum()) + self.bending.value(self._edge_values(hinges.s))

    def _hinges(self, X: np.ndarray) -> "_HingeGeometry":
        """The hinges' geometry at X, kept for the next call: Newton's line search evaluates the
        energy at the point it accepts, whose gradient and Hessians come next."""
        last = self._last_hinges
        if last is not None and last[0].shape == X.shape and np.array_equal(last[0], X):
            return last[1]
        hinges = _HingeGeometry(X, self.topo.hinge)
        self._last_hinges = (np.array(X, dtype=float), hinges)
        return hinges

    def parts(self, X: np.ndarray) -> tuple[float, float]:
        """(stretching, bending) energies."""
        W, _, _ = stretch_energy(X, self.F, self.abar, self.stretch_coef, self.nu, forms=self._stretch_forms)
        s_h, _, _ = hinge_tan(X, self.topo.hinge)
        return float(W.sum()), self.bending.value(self._edge_values(s_h))

    def gradient(self, X: np.ndarray) -> np.ndarray:
        """∇E (3n,), xyz interleaved per vertex."""
        _, g, _ = stretch_energy(X, self.F, self.abar, self.stretch_coef, self.nu, derivatives=1,
                                 forms=self._stretch_forms)
        s_h, gs, _ = hinge_tan(X, self.topo.hinge, derivatives=1)
        lam = (self.bending.H @ self._edge_values(s_h) + self.bending.g)[self._hedge]
        out = np.bincount(self._fdof.ravel(), weights=g.ravel(), minlength=3 * self.n)
        out += np.bincount(self._hdof.ravel(), weights=(lam[:, None] * gs).ravel(), minlength=3 * self.n)
        return out

    def rest_sensitivities(self, X: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The mixed derivatives of vᵀ∇E(X) with respect to the face parameters: b̄ (m, 3) in the edge
        basis, the stretching coefficients (m,) and the bending coefficients (m,) (``deploy.optimize``'s
        adjoint: dJ/dp = −λᵀ ∂∇E/∂p). ∇E is linear in b̄ (E_b's g = G b̄ per face) and each face's
        terms are linear in its coefficient, so these are exact: per face, the directional derivative
        along v of its own terms, divided by its coefficient, and Gᵀ ds for b̄ (ds = ∂s/∂x v per edge).

        Parameters
        ----------
        X : (n, 3) positions; v : (3n,) a direction, xyz interleaved per vertex.
        """
        v = np.asarray(v, dtype=float).ravel()
        if v.shape != (3 * self.n,):
            raise ValueError(f"v must have shape ({3 * self.n},), got {v.shape}")
        _, g, _ = stretch_energy(X, self.F, self.abar, self.stretch_coef, self.nu, derivatives=1,
                                 forms=self._stretch_forms)
        d_stretch = (g * v[self._fdof]).sum(axis=1) / self.stretch_coef
        s_h, gs, _ = hinge_tan(X, self.topo.hinge, derivatives=1)
        ds = self._edge_values((gs * v[self._hdof]).sum(axis=1))[self.topo.face_edge]      # (m, 3)
        s = self._edge_values(s_h)[self.topo.face_edge]
        b = self.bending
        face_terms = np.einsum("ki,kij,kj->k", ds, b.face_H, s) + (ds * b.face_g).sum(axis=1)
        d_bend = face_terms / self._bend_coef
        d_bbar = np.einsum("kij,ki->kj", b.face_G, ds)
        return d_bbar, d_stretch, d_bend

    def gradient_and_hessian(self, X: np.ndarray, project: bool = True
                             ) -> tuple[np.ndarray, sp.csr_matrix]:
        """∇E (3n,) and the Hessian (3n, 3n) sparse: exact, or (``project``) positive semidefinite.

        The positive semidefinite approximation keeps the parts of the Hessian that are positive by
        construction and projects the rest per element: the membrane's Jᵀ ∇²W J (W is convex in a)
        plus the stress term with the stress's positive part only (the 2 × 2 stress projected in
        closed form per face), and the bending's Gauss–Newton term Jᵀ H_s J without the hinges'
        second derivatives. So −H⁻¹∇E is a descent direction even where the sheet is compressed.
        """
        grad, exact, psd = self.gradient_and_hessians(X)
        return grad, (psd() if project else exact()).tocsr()

    def gradient_and_hessians(self, X: np.ndarray, free: np.ndarray | None = None, lower: bool = False):
        """(∇E, exact(), psd()): the gradient (3n,) and two functions assembling each Hessian on demand,
        on the rows and columns ``free`` (sorted dof indices; default all) as CSC with sorted indices;
        with ``lower``, only its lower triangle (what the solver's Cholesky factorization reads).

        The Hessian's sparsity is fixed, so each is one sparse product per group of element blocks
        into the data of a pattern made once per ``free`` set (no COO conversion, sort or slicing per
        call; ``HessianPattern``).
        The bending's Gauss–Newton term Jᵀ H_s J is summed per face over its three hinges:
        J_fᵀ H_f J_f on the face and its three neighbours' opposite vertices (18 dofs).
        """
        _, g, parts = stretch_energy(X, self.F, self.abar, self.stretch_coef, self.nu, derivatives=3,
                                     forms=self._stretch_forms)
        GN_e, Wa = parts
        hinges = self._hinges(X)
        s_h, gs = hinges.s, hinges.gradient()
        lam = (self.bending.H @ self._edge_values(s_h) + self.bending.g)[self._hedge]
        n3 = 3 * self.n
        grad = np.bincount(self._fdof.ravel(), weights=g.ravel(), minlength=n3)
        grad += np.bincount(self._hdof.ravel(), weights=(lam[:, None] * gs).ravel(), minlength=n3)
        pattern = self._pattern(free, lower)
        Jf = np.zeros(len(self.F) * 54)
        Jf[self._nb_to] = gs.ravel()[self._nb_from]
        Jf = Jf.reshape(-1, 3, 18)
        gauss_newton = np.swapaxes(Jf, 1, 2) @ self.bending.face_H @ Jf

        def exact() -> sp.csc_matrix:
            He = E_TO_X.T @ (GN_e + _stress_term(Wa)) @ E_TO_X
            hs = hinges.hessian(lam)                   # the hinges' second derivatives: only here
            return pattern.assemble((He, hs, gauss_newton))

        def psd() -> sp.csc_matrix:
            He = E_TO_X.T @ (GN_e + _stress_term(Wa, positive=True)) @ E_TO_X
            return pattern.assemble((He, None, gauss_newton))

        return grad, exact, psd

    def _pattern(self, free: np.ndarray | None, lower: bool = False) -> "HessianPattern":
        key = None if free is None else np.asarray(free, dtype=np.int64)
        cached = getattr(self, "_cached_pattern", None)
        if cached is not None and cached.lower == lower and (
                cached.free is None if key is None else cached.free is not None and np.array_equal(cached.free, key)):
            return cached
        blocks = [self.F, self.topo.hinge, self._nb_vertices]
        # the hinges' blocks come batch-last (12, 12, h) from _HingeGeometry.hessian
        self._cached_pattern = HessianPattern(blocks, 3 * self.n, key, batch_last=(False, True, False),
                                              lower=lower)
        return self._cached_pattern

    def _face_neighbourhoods(self) -> None:
        """Per face its three vertices and, across each edge, the opposite vertex (itself on the
        boundary): the 18 dofs a face's bending Gauss–Newton block touches, and where each of its
        hinges' four vertices sits among them."""
        F, topo = self.F, self.topo
        hinge_of_edge = np.full(topo.n_edges, -1, dtype=np.int64)
        hinge_of_edge[topo.hinge_edge] = np.arange(len(topo.hinge))
        hid = hinge_of_edge[topo.face_edge]                                 # (m, 3), −1 on the boundary
        hv = topo.hinge[np.maximum(hid, 0)]                                 # (m, 3, 4)
        opp = np.where(hv[:, :, 0] == F, hv[:, :, 3], hv[:, :, 0])
        nb = np.concatenate([F, np.where(hid >= 0, opp, F)], axis=1)        # (m, 6)
        self._nb_vertices = nb
        f_idx, e_idx = np.nonzero(hid >= 0)
        loc = np.argmax(hv[f_idx, e_idx][:, :, None] == nb[f_idx][:, None, :], axis=2)   # (k, 4)
        # J_f (m, 3, 6, 3) flattened: hinge k's gradient (12,) goes to face f_idx[k], edge e_idx[k],
        # its four vertices' places loc[k] among the six
        self._nb_to = ((54 * f_idx + 18 * e_idx)[:, None, None] + 3 * loc[:, :, None] + np.arange(3)).ravel()
        self._nb_from = (12 * hid[f_idx, e_idx][:, None] + np.arange(12)).ravel()


class HessianPattern:
    """The fixed sparsity of a sum of dense element blocks over vertices (three dofs each, xyz
    interleaved), restricted to the dofs ``free``, and the sparse maps that sum the blocks into it.

    Parameters
    ----------
    blocks : per group the vertices (k, v) of each element: element k's block (3v × 3v) sits at the
        dofs of vertices[k].
    n : the number of dofs (3 × vertices); free : sorted dofs kept (None: all).
    batch_last : per group, its values come as (3v, 3v, k) rather than (k, 3v, 3v) (default: none).
    lower : only the lower triangle (row ≥ column), all a Cholesky factorization reads: half the sums.

    The pattern is made per vertex pair (3 × 3 dense blocks, one ``unique`` over the pairs, not over
    every dof pair); ``assemble`` is one sparse matrix-vector product per group (each slot sums its
    contributions in the order of the values, as a ``bincount`` would: the same sums).
    """

    def __init__(self, blocks: list[np.ndarray], n: int, free: np.ndarray | None,
                 batch_last: tuple[bool, ...] | None = None, lower: bool = False) -> None:
        self.free, self.lower = free, lower
        nv = n // 3
        pairs = [(np.repeat(v, v.shape[1], axis=1), np.tile(v, (1, v.shape[1]))) for v in blocks]  # (k, v²)
        keys = np.concatenate([(c * nv + r).ravel() for r, c in pairs])           # column-major
        vkeys, vinv = np.unique(keys, return_inverse=True)
        vcol = vkeys // nv
        vstart = np.searchsorted(vcol, np.arange(nv + 1))
        deg = np.diff(vstart)
        # the full (all dofs, both triangles) CSC: column 3J + b holds rows 3I + a, I over J's vertex
        # rows in order; its entry sits at 9 vstart[J] + 3 deg[J] b + 3 (p − vstart[J]) + a
        p = np.arange(len(vkeys))
        J, I = vcol, vkeys % nv
        ab = np.arange(3)
        full_pos = (9 * vstart[J] - 3 * vstart[J] + 3 * p)[:, None, None] + ab[:, None] \
            + (3 * deg[J])[:, None, None] * ab[None, :]                          # (pairs, a, b)
        order = np.empty(9 * len(p), dtype=np.int64)
        order[full_pos.ravel()] = np.arange(9 * len(p))
        row = (3 * I[:, None, None] + ab[:, None] + 0 * ab[None, :]).ravel()[order]
        col = (3 * J[:, None, None] + 0 * ab[:, None] + ab[None, :]).ravel()[order]
        index = np.arange(n) if free is None else np.full(n, -1, dtype=np.int64)
        if free is not None:
            index[free] = np.arange(len(free))
        keep = (index[row] >= 0) & (index[col] >= 0)
        if lower:
            keep &= row >= col
        remap = np.where(keep, np.cumsum(keep) - 1, -1)
        nf = n if free is None else len(free)
        self.nnz = int(keep.sum())
        self.indices = index[row[keep]].astype(np.int32)
        self.indptr = np.searchsorted(index[col[keep]], np.arange(nf + 1)).astype(np.int32)
        self.shape = (nf, nf)
        self.scatter = []
        start = 0
        for g, (v, (r, c)) in enumerate(zip(blocks, pairs)):
            k, m = v.shape
            pk = vinv[start:start + r.size].reshape(k, m, m)                     # (k, i, j) pair ids
            start += r.size
            fp = (9 * vstart[c.reshape(k, m, m)] - 3 * vstart[c.reshape(k, m, m)] + 3 * pk)[:, :, None, :, None] \
                + ab[None, None, :, None, None] + (3 * deg[c.reshape(k, m, m)])[:, :, None, :, None] * ab
            slot = remap[fp]                                                     # (k, i, a, j, b)
            if batch_last is not None and batch_last[g]:
                slot = np.moveaxis(slot, 0, -1)
            slot = slot.ravel()
            ok = np.flatnonzero(slot >= 0)
            self.scatter.append(sp.csr_matrix((np.ones(len(ok)), (slot[ok], ok)), shape=(self.nnz, slot.size)))

    def assemble(self, values: tuple[np.ndarray | None, ...]) -> sp.csc_matrix:
        """The matrix with the element blocks ``values`` (one (k, d, d) array, or (d, d, k) for a
        ``batch_last`` group, or None per group); with ``lower``, its lower triangle."""
        data = np.zeros(self.nnz)
        for S, v in zip(self.scatter, values):
            if v is not None:
                data += S @ np.ascontiguousarray(v).ravel()
        H = sp.csc_matrix((data, self.indices, self.indptr), shape=self.shape)
        H.has_sorted_indices = True
        return H


def _stress_term(Wa: np.ndarray, positive: bool = False) -> np.ndarray:
    """The membrane Hessian's stress term kron(G, I3) (k, 6, 6), G = [[2 W_a11, W_a12], [W_a12, 2 W_a22]];
    with ``positive``, G's positive part (closed-form 2 × 2 eigen-decomposition)."""
    G = np.empty((len(Wa), 2, 2))
    G[:, 0, 0], G[:, 1, 1] = 2 * Wa[:, 0], 2 * Wa[:, 2]
    G[:, 0, 1] = G[:, 1, 0] = Wa[:, 1]
    if positive:
        tr = G[:, 0, 0] + G[:, 1, 1]
        disc = np.sqrt(0.25 * (G[:, 0, 0] - G[:, 1, 1]) ** 2 + G[:, 0, 1] ** 2)
        l1, l2 = 0.5 * tr + disc, 0.5 * tr - disc                     # l1 ≥ l2
        # eigenvector of l1: (G01, l1 − G00) or (l1 − G11, G01), whichever is longer
        v = np.stack([G[:, 0, 1], l1 - G[:, 0, 0]], -1)
        alt = np.stack([l1 - G[:, 1, 1], G[:, 0, 1]], -1)
        use = np.linalg.norm(alt, axis=1) > np.linalg.norm(v, axis=1)
        v[use] = alt[use]
        nv = np.linalg.norm(v, axis=1)
        v = np.where(nv[:, None] > 0, v / np.where(nv > 0, nv, 1)[:, None], np.array([1.0, 0.0]))
        w = np.stack([-v[:, 1], v[:, 0]], -1)
        G = (np.maximum(l1, 0)[:, None, None] * _outer(v, v) + np.maximum(l2, 0)[:, None, None] * _outer(w, w))
    return (G[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]).reshape(len(G), 6, 6)
