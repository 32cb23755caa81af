"""The k1 line field: the curvature lines where they are defined, smooth where they are not (§4.3).

A line at angle β in a face's frame is the unit complex number z = e^{2iβ} (the squared
representation of Knöppel, Crane, Pinkall, Schröder 2013, in which the two opposite directions of
a line agree). The smoothness energy is Σ_edges w |z_f − r_fg z_g|², r_fg the Levi-Civita transport
across the shared edge (``connection_laplacian``: the matrix A).

Two fields are made here:

- ``"aligned"`` (the default): a data term pulls each face toward its own k1 direction q̂_f with a
  weight that grows with how well k1 is defined there, the curvature anisotropy
  a = (|κ1| − |κ2|) / (|κ1| + |κ2|):

      min_z  zᴴ A z + ρ Σ_f a_f² A_f |z_f − q̂_f|²,   i.e.   (A + ρ G B) z = ρ G B q̂

  with B the face areas of the surface scaled to unit area and G = diag(a²). Where a → 0
  (umbilic regions, the H = 0 diagonals of a saddle, a flat plane) the data term fades and the
  field is the smooth (harmonic) continuation of its surroundings; where k1 is well defined it is
  followed within the mesh's own accuracy. ρ = 1 / ℓ² sets the smoothing length ℓ over which
  the field averages the estimated k1: ℓ = 0.02 (1 + λ) in units of √area, about a ribbon width on
  a design of 100 mm, below what the ribbons resolve. ``smoothing_lambda`` λ ∈ (−1, 0] is thus the
  relative change of that length: 0 is the default, −0.1 smooths 10 % less (Table 1's −0.01 and
  −0.1 are such slight decreases), and toward −1 the field is the raw per-face k1 wherever a > 0.
- ``"kcps13"``: the previous engine's field, KCPS13 §6's (A − λB) z = B q with q = (|κ1| − |κ2|) q̂,
  λ ≤ 0 in units of the surface scaled to unit area (λ = 0 smooths far from k1: ~3° on a saddle).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .curvature import Curvature
from .frames import FaceFrames
from .linalg import TwoLevelSolver

_SHIFT = 1e-8          # keeps the matrix definite where the smoothest field is parallel (λ1 = 0)
_UMBILIC_ONLY = 0.01   # no curvature direction anywhere below this anisotropy

#: ℓ0: the smoothing length of the aligned field at λ = 0, in units of √(surface area).
SMOOTHING_LENGTH = 0.02

#: Faces whose anisotropy (|κ1| − |κ2|) / (|κ1| + |κ2|) does not exceed this are umbilic for the
#: report (design-format.md): k1 is not defined well enough there to measure a deviation from it.
ANISOTROPY_THRESHOLD = 0.3

#: Meshes with more faces solve the aligned field iteratively (two-level CG) instead of directly.
DIRECT_SOLVE_FACES = 30_000

#: Faces per patch of the iterative solve's coarse space, and the smoothing sweeps of its result.
PATCH_FACES = 16
JACOBI_SWEEPS = 6

#: The steps toward a unit-length field after the linear solve, and their weight (× ρ).
UNIT_ITERATIONS = 5
UNIT_WEIGHT = 0.2

FieldMethod = Literal["aligned", "kcps13"]


@dataclass(frozen=True)
class LineField:
    """The ribbon direction field on the target surface.

    Attributes
    ----------
    angle : (m,) direction of the line in each face's frame, radians from e1, in [0, π).
    direction : (m, 3) a unit vector along the line (its sign is arbitrary: it is a line).
    anisotropy : (m,) (|κ1| − |κ2|) / max(|κ1| + |κ2|, κ_flat) of the estimated curvature.
    umbilic : (m,) True where the anisotropy is at most the umbilic tolerance: k1 is not defined
        there and the field is the smooth continuation from around.
    aligned : bool, False when the whole surface is umbilic (a plane, a sphere): the field is
        then the smoothest line field, in a direction of its own choosing (Fig. 11a).
    singular_vertices : (s,) interior vertices where the field has a nonzero index.
    singular_index : (s,) their indices, multiples of ±1/2.
    method : "aligned" or "kcps13".
    one_family : True when the field follows one family of curvature lines through the ambiguous
        saddle regions (``saddle_family``) instead of the largest |κ|.
    """

    angle: np.ndarray
    direction: np.ndarray
    anisotropy: np.ndarray
    umbilic: np.ndarray
    aligned: bool
    singular_vertices: np.ndarray
    singular_index: np.ndarray
    method: str
    one_family: bool = False

    @property
    def local(self) -> np.ndarray:
        """(m, 2) unit vectors along the line in the face frames."""
        return np.column_stack([np.cos(self.angle), np.sin(self.angle)])


def interior_edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Faces on either side of every interior edge.

    Returns
    -------
    f, g : (k,) the face where the edge runs i → j and the face where it runs j → i.
    ij : (k, 2) the vertices i < j.
    """
    m = len(F)
    he = np.stack([F, np.roll(F, -1, axis=1)], axis=2).reshape(-1, 2)        # (3m, 2): i -> j
    face = np.repeat(np.arange(m), 3)
    key = np.sort(he, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks = key[order]
    same = np.all(ks[1:] == ks[:-1], axis=1)
    first, second = order[:-1][same], order[1:][same]
    forward = he[first, 0] == key[first, 0]            # which of the pair runs low -> high
    f = np.where(forward, face[first], face[second])
    g = np.where(forward, face[second], face[first])
    ij = np.sort(he[first], axis=1)
    return f, g, ij


@dataclass(frozen=True)
class EdgeTransport:
    """The interior edges of a mesh with the discrete Levi-Civita transport across them.

    Attributes
    ----------
    f, g : (k,) the face where the edge runs i → j and the face where it runs j → i.
    ij : (k, 2) the vertices i < j.
    r : (k,) r_fg = e^{2i(α_f − α_g)}, α the angle of the edge in each face's frame: it carries a
        line (squared representation) from g's frame into f's (unfolding the two faces).
    w : (k,) w = |e| / |c_f − c_g|, a two-point finite-volume weight on the dual edge (> 0).
    """

    f: np.ndarray
    g: np.ndarray
    ij: np.ndarray
    r: np.ndarray
    w: np.ndarray


def edge_transport(V: np.ndarray, F: np.ndarray, frames: FaceFrames) -> EdgeTransport:
    """The interior edges of (V, F) and the transport across them (``EdgeTransport``)."""
    f, g, ij = interior_edges(F)
    e = V[ij[:, 1]] - V[ij[:, 0]]
    alpha_f = np.arctan2(np.einsum("ij,ij->i", e, frames.e2[f]), np.einsum("ij,ij->i", e, frames.e1[f]))
    alpha_g = np.arctan2(np.einsum("ij,ij->i", e, frames.e2[g]), np.einsum("ij,ij->i", e, frames.e1[g]))
    centroid = V[F].mean(axis=1)
    w = np.linalg.norm(e, axis=1) / np.linalg.norm(centroid[f] - centroid[g], axis=1)
    return EdgeTransport(f=f, g=g, ij=ij, r=np.exp(2j * (alpha_f - alpha_g)), w=w)


def connection_laplacian(V: np.ndarray, F: np.ndarray, frames: FaceFrames,
                         transport: EdgeTransport | None = None) -> sp.csc_matrix:
    """A: the Hermitian energy matrix of Σ_edges w |z_f − r_fg z_g|² for 2-direction fields.

    Returns
    -------
    (m, m) complex sparse matrix, positive semi-definite.
    """
    t = transport or edge_transport(V, F, frames)
    rows = np.concatenate([t.f, t.g, t.f, t.g])
    cols = np.concatenate([t.f, t.g, t.g, t.f])
    vals = np.concatenate([t.w, t.w, -t.w * t.r, -t.w * np.conj(t.r)]).astype(complex)
    return sp.csc_matrix((vals, (rows, cols)), shape=(len(F), len(F)))


def _bbox_diagonal(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def curvature_anisotropy(curvature: Curvature, diagonal: float) -> np.ndarray:
    """(m,) a = (|κ1| − |κ2|) / max(|κ1| + |κ2|, κ_flat), κ_flat = 0.1 / ``diagonal``.

    The floor makes a (numerically) flat region umbilic (a = 0) instead of letting estimation
    noise there look anisotropic: a radius ten times the surface's size is flat for our purposes.
    """
    k1, k2 = np.abs(curvature.kappa1), np.abs(curvature.kappa2)
    return (k1 - k2) / np.maximum(k1 + k2, 0.1 / max(diagonal, 1e-300))


def smoothing_length(smoothing_lambda: float) -> float:
    """ℓ = ℓ0 (1 + λ) of the aligned field, in units of √area, for λ ∈ (−1, 0]."""
    if not -1.0 < smoothing_lambda <= 0.0:
        raise ValueError(f"smoothing_lambda = {smoothing_lambda}: must be in (-1, 0] for the aligned "
                         "field (0 is the default, -0.1 smooths 10 % less); the previous engine's "
                         "unbounded λ is line_field = 'kcps13' in the solver settings")
    return SMOOTHING_LENGTH * (1.0 + smoothing_lambda)


def face_clusters(V: np.ndarray, F: np.ndarray, frames: FaceFrames, clusters: int) -> sp.csr_matrix:
    """P (m, k): faces grouped into about ``clusters`` patches of equal area, a line field on a patch
    carried to its faces (z_f = e^{2iα_f} z_c, α_f the angle of the patch's reference tangent in
    face f's frame). The coarse space of ``linalg.TwoLevelSolver``.
    """
    C = V[F].mean(axis=1)
    cell = np.sqrt(frames.area.sum() / max(clusters, 1))
    ijk = np.floor((C - C.min(axis=0)) / cell).astype(np.int64)
    dims = ijk.max(axis=0) + 1
    _, owner = np.unique((ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2], return_inverse=True)
    k = int(owner.max()) + 1
    normal = np.zeros((k, 3))
    np.add.at(normal, owner, frames.n * frames.area[:, None])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    axis = np.eye(3)[np.argmin(np.abs(normal), axis=1)]           # the axis least along the normal
    ref = axis - np.einsum("ij,ij->i", axis, normal)[:, None] * normal
    ref = (ref / np.linalg.norm(ref, axis=1, keepdims=True))[owner]
    alpha = np.arctan2(np.einsum("ij,ij->i", ref, frames.e2), np.einsum("ij,ij->i", ref, frames.e1))
    return sp.csr_matrix((np.exp(2j * alpha), (np.arange(len(F)), owner)), shape=(len(F), k))


def _solve_aligned(A: sp.csc_matrix, anisotropy: np.ndarray, q: np.ndarray, area: np.ndarray,
                   rho: float, V: np.ndarray, F: np.ndarray, frames: FaceFrames) -> np.ndarray:
    """The aligned field: the linear solve, then ``UNIT_ITERATIONS`` steps that pull it toward unit
    length with weight ``UNIT_WEIGHT`` ρ (1 − a)² (where k1 is defined, the data term rules).

    Where k1 turns by 90° across an umbilic ring (the foot of a bump, |κr| = |κθ|) the linear field
    interpolates between opposite values z and −z and passes through 0, leaving a row of ±½
    singularity pairs along the ring; pulled toward |z| = 1 it turns through the ring instead.

    Small meshes are factorized. On large ones the steps are taken on the Galerkin coarse problem
    of face patches (``face_clusters``; the field is smooth at the patches' scale) and only the last
    is solved on the faces, by CG preconditioned with the same patches, from the coarse solution.
    """
    data_weight = rho * anisotropy ** 2 * area + _SHIFT * area
    unit_weight = UNIT_WEIGHT * rho * np.clip(1.0 - anisotropy / ANISOTROPY_THRESHOLD, 0.0, 1.0) ** 2 * area
    b = data_weight * q
    M1 = (A + sp.diags(data_weight)).tocsc()
    M2 = (A + sp.diags(data_weight + unit_weight)).tocsc()
    if len(F) <= DIRECT_SOLVE_FACES:
        z = spla.spsolve(M1, b)
        solve2 = spla.factorized(M2)
        for _ in range(UNIT_ITERATIONS):
            z = solve2(b + unit_weight * _unit(z))
        return z
    P = face_clusters(V, F, frames, clusters=len(F) // PATCH_FACES)
    PH = P.conj().T.tocsr()
    fine = TwoLevelSolver(M2, P, rtol=1e-4, max_iterations=500)   # ~0.003° of the exact solve
    bc = PH @ b
    z_c = spla.splu((PH @ M1 @ P).tocsc()).solve(bc)
    patch_unit_weight = abs(P).T @ unit_weight        # Pᴴ diag(w) P: P has one unit entry per row
    for _ in range(UNIT_ITERATIONS - 1):
        z_c = fine.coarse_solve(bc + patch_unit_weight * _unit(z_c))
    # the last step on the faces, from the coarse field smoothed by a few Jacobi sweeps (constant
    # over each patch, its unit-length pull would leave the patches' edges in the field)
    z = P @ z_c
    inv_diag = 1.0 / M2.diagonal().real
    rhs = b + unit_weight * _unit(z)
    for _ in range(JACOBI_SWEEPS):
        z = z + 0.8 * inv_diag * (rhs - M2 @ z)
    rhs = b + unit_weight * _unit(z)
    z, converged = fine.solve(rhs, x0=z)
    return z if converged else spla.spsolve(M2, rhs)


def _unit(z: np.ndarray) -> np.ndarray:
    return z / np.maximum(np.abs(z), 1e-300)


def singularities(V: np.ndarray, F: np.ndarray, frames: FaceFrames, z: np.ndarray,
                  transport: EdgeTransport | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Interior vertices where the line field z (m,) (squared representation) has a nonzero index.

    The index of vertex v is (Σ δ + 2 d_v) / (4π) (KCPS13 §5.1, for lines): δ the field's turn
    across each edge around v relative to the transport, d_v the angle defect.

    Returns
    -------
    vertices : (s,) vertex indices; index : (s,) their indices (multiples of ±1/2).
    """
    t = transport or edge_transport(V, F, frames)
    u = _unit(z)
    delta = np.angle(u[t.f] * np.conj(t.r * u[t.g]))            # turn crossing from g into f
    ij = t.ij
    n = len(V)
    # counter-clockwise around i (the edge's first vertex) the walk enters f from g; around j it
    # leaves f into g
    turn = np.bincount(ij[:, 0], weights=delta, minlength=n) - np.bincount(ij[:, 1], weights=delta, minlength=n)
    P = V[F]
    a = np.roll(P, -1, axis=1) - P
    b = np.roll(P, 1, axis=1) - P
    corner = np.arctan2(np.linalg.norm(np.cross(a, b), axis=2), np.einsum("fkc,fkc->fk", a, b))
    defect = 2 * np.pi - np.bincount(F.ravel(), weights=corner.ravel(), minlength=n)
    interior = np.ones(n, dtype=bool)
    he = np.sort(np.stack([F, np.roll(F, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    key, count = np.unique(he[:, 0] * n + he[:, 1], return_counts=True)
    boundary = key[count == 1]
    interior[boundary // n] = False
    interior[boundary % n] = False
    index = np.rint((turn + 2 * defect) / (2 * np.pi)) / 2
    sing = np.flatnonzero(interior & (index != 0))
    return sing, index[sing]


def curvature_line_field(V: np.ndarray, F: np.ndarray, frames: FaceFrames, curvature: Curvature,
                         smoothing_lambda: float = 0.0, umbilic_tolerance: float = ANISOTROPY_THRESHOLD,
                         method: FieldMethod = "aligned",
                         targets: tuple[np.ndarray, np.ndarray] | None = None) -> LineField:
    """The line field along k1 (§4.3), by ``method`` (module docstring).

    Parameters
    ----------
    V : (n, 3); F : (m, 3); frames, curvature : of the same mesh.
    smoothing_lambda : λ: for "aligned" in (−1, 0], the relative change of the smoothing length;
        for "kcps13" ≤ 0, KCPS13's λ on the surface scaled to unit area.
    umbilic_tolerance : faces whose anisotropy does not exceed this are marked umbilic.
    targets : (angle (m,), weight (m,)) in place of k1's angle and the anisotropy as the aligned field's
        data term (``saddle_family``); the field's ``anisotropy`` and ``umbilic`` stay the curvature's.
    """
    if method not in ("aligned", "kcps13"):
        raise ValueError(f"line field method {method!r}: must be 'aligned' or 'kcps13'")
    if targets is not None and method != "aligned":
        raise ValueError(f"targets are the aligned field's data term, not {method!r}'s")
    if method == "kcps13" and smoothing_lambda > 0:
        raise ValueError(f"smoothing_lambda = {smoothing_lambda}: must be ≤ 0 (0 is the default; "
                         "negative values smooth less)")
    area = frames.area / frames.area.sum()
    transport = edge_transport(V, F, frames)
    A = connection_laplacian(V, F, frames, transport)
    anisotropy = curvature_anisotropy(curvature, _bbox_diagonal(V))
    # below 1 % anisotropy anywhere the directions are estimation noise (a plane, a sphere)
    aligned = bool((anisotropy if targets is None else targets[1]).max() > _UMBILIC_ONLY)
    if not aligned:
        z = _smoothest(A, area)
    elif method == "aligned":
        rho = 1.0 / smoothing_length(smoothing_lambda) ** 2
        angle, weight = targets if targets is not None else (curvature.angle, anisotropy)
        z = _solve_aligned(A, np.clip(weight, 0.0, 1.0), np.exp(2j * angle), area, rho, V, F, frames)
    else:
        B = sp.diags((area * (_SHIFT - smoothing_lambda)).astype(complex))
        q = curvature.alignment
        q_norm = np.sqrt(np.sum(area * np.abs(q) ** 2))
        z = spla.spsolve((A + B).tocsc(), area * q / q_norm)
    angle = np.mod(0.5 * np.angle(z), np.pi)
    local = np.column_stack([np.cos(angle), np.sin(angle)])
    sing, index = singularities(V, F, frames, z, transport)
    return LineField(angle=angle, direction=frames.to_world(local), anisotropy=anisotropy,
                     umbilic=anisotropy <= umbilic_tolerance, aligned=aligned, singular_vertices=sing,
                     singular_index=index, method=method, one_family=targets is not None)


def _smoothest(A: sp.csc_matrix, area: np.ndarray) -> np.ndarray:
    """The smoothest line field: the eigenvector of the smallest eigenvalue of (A, B) by inverse
    iteration, from a fixed start so that the same mesh always gives the same field."""
    solve = spla.factorized((A + sp.diags(_SHIFT * area)).tocsc())
    z = np.ones(len(area), dtype=complex)
    for _ in range(30):
        z = solve(area * z)
        z /= np.sqrt(np.sum(area * np.abs(z) ** 2))
    return z


def field_k1_deviation(field: LineField, curvature: Curvature) -> dict[str, float] | None:
    """The angle between the field and the target's own k1 on faces where k1 is defined
    (anisotropy above ``ANISOTROPY_THRESHOLD``): median, mean and p95 in degrees; None where no
    face has a defined k1 (there is nothing to deviate from)."""
    d = np.mod(field.angle - curvature.angle, np.pi)
    deg = np.degrees(np.minimum(d, np.pi - d))[field.anisotropy > ANISOTROPY_THRESHOLD]
    if len(deg) == 0:
        return None
    return {"median": float(np.median(deg)), "mean": float(deg.mean()), "p95": float(np.percentile(deg, 95))}
