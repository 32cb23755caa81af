"""The k1 line field: a globally optimal, curvature-aligned 2-direction field (§4.3).

Knöppel, Crane, Pinkall, Schröder 2013, "Globally Optimal Direction Fields", on faces: a line
at angle β in a face's frame is the unit complex number z = e^{2iβ} (the squared
representation, in which the two opposite directions of a line agree). The smoothness energy
is Σ_edges w |z_f − r_fg z_g|² with r_fg the Levi-Civita transport across the shared edge, and
the curvature-aligned field solves

    (A − λ B) z = B q̂                                                          (KCPS13 §6)

with q̂ the normalized curvature field of ``curvature.Curvature.alignment`` (largest |κ|,
weighted by |κ1| − |κ2|) and B the face areas of the surface scaled to unit area, so λ does not
depend on the size of the mesh. λ = 0 is the paper's default; negative λ follows the
curvature directions more closely (smooths less), as in Table 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .curvature import Curvature
from .frames import FaceFrames

_SHIFT = 1e-8          # keeps A − λB definite where the smoothest field is parallel (λ1 = 0)
_UMBILIC_ONLY = 1e-9   # |q| below this share of the curvature scale: nothing to align with


@dataclass(frozen=True)
class LineField:
    """The ribbon direction field on the target surface.

    Attributes
    ----------
    angle : (m,) direction of the line in each face's frame, radians from e1, in [0, π).
    direction : (m, 3) a unit vector along the line (its sign is arbitrary: it is a line).
    umbilic : (m,) True where |κ1| ≈ |κ2|: k1 is not defined there, the field is the smooth
        continuation from around.
    aligned : bool, False when the whole surface is umbilic (a plane, a sphere): the field is
        then the smoothest line field, in a direction of its own choosing (Fig. 11a).
    """

    angle: np.ndarray
    direction: np.ndarray
    umbilic: np.ndarray
    aligned: bool

    @property
    def local(self) -> np.ndarray:
        """(m, 2) unit vectors along the line in the face frames."""
        return np.column_stack([np.cos(self.angle), np.sin(self.angle)])


def interior_edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Faces on either side of every interior edge.

    Returns
    -------
    f, g : (k,) the face where the edge runs i → j and the face where it runs j → i.
    ij : (k, 2) the vertices i, j.
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


def connection_laplacian(V: np.ndarray, F: np.ndarray, frames: FaceFrames) -> sp.csc_matrix:
    """A: the Hermitian energy matrix of Σ_edges w |z_f − r_fg z_g|² for 2-direction fields.

    r_fg = e^{2i(α_f − α_g)}, α the angle of the shared edge in each face's frame (unfolding the
    two faces about the edge is the discrete Levi-Civita transport); w = |e| / |c_f − c_g|, a
    two-point finite-volume weight on the dual edge (always positive).

    Returns
    -------
    (m, m) complex sparse matrix, positive semi-definite.
    """
    f, g, ij = interior_edges(F)
    e = V[ij[:, 1]] - V[ij[:, 0]]
    alpha_f = np.arctan2(np.einsum("ij,ij->i", e, frames.e2[f]), np.einsum("ij,ij->i", e, frames.e1[f]))
    alpha_g = np.arctan2(np.einsum("ij,ij->i", e, frames.e2[g]), np.einsum("ij,ij->i", e, frames.e1[g]))
    r = np.exp(2j * (alpha_f - alpha_g))
    centroid = V[F].mean(axis=1)
    w = np.linalg.norm(e, axis=1) / np.linalg.norm(centroid[f] - centroid[g], axis=1)
    m = len(F)
    rows = np.concatenate([f, g, f, g])
    cols = np.concatenate([f, g, g, f])
    vals = np.concatenate([w, w, -w * r, -w * np.conj(r)]).astype(complex)
    return sp.csc_matrix((vals, (rows, cols)), shape=(m, m))


def curvature_line_field(V: np.ndarray, F: np.ndarray, frames: FaceFrames, curvature: Curvature,
                         smoothing_lambda: float = 0.0, umbilic_tolerance: float = 0.1) -> LineField:
    """The globally optimal line field aligned with k1 (KCPS13 with the paper's |κ| change, §4.3).

    Parameters
    ----------
    V : (n, 3); F : (m, 3); frames, curvature : of the same mesh.
    smoothing_lambda : λ ≤ 0 (Table 1); in units of the surface scaled to unit area.
    umbilic_tolerance : a face is umbilic where |κ1| − |κ2| < tolerance · max(|κ1|, κ_flat), with
        κ_flat = 0.1 / (bounding-box diagonal), below which a surface is flat for our purposes.
    """
    if smoothing_lambda > 0:
        raise ValueError(f"smoothing_lambda = {smoothing_lambda}: must be ≤ 0 (0 is the default; "
                         "negative values smooth less)")
    area = frames.area / frames.area.sum()
    B = sp.diags(area.astype(complex), format="csc")
    A = connection_laplacian(V, F, frames)
    solve = spla.factorized((A + (_SHIFT - smoothing_lambda) * B).tocsc())

    q = curvature.alignment
    scale = np.sqrt(np.sum(area * (np.abs(curvature.kappa1) + np.abs(curvature.kappa2)) ** 2))
    q_norm = np.sqrt(np.sum(area * np.abs(q) ** 2))
    aligned = bool(q_norm > _UMBILIC_ONLY * max(scale, 1e-300))
    if aligned:
        z = solve(area * q / q_norm)
    else:
        # Smoothest field: the eigenvector of the smallest eigenvalue of (A, B) by inverse
        # iteration, from a fixed start so that the same mesh always gives the same field.
        z = np.ones(len(F), dtype=complex)
        for _ in range(30):
            z = solve(area * z)
            z /= np.sqrt(np.sum(area * np.abs(z) ** 2))
    angle = np.mod(0.5 * np.angle(z), np.pi)
    diag = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    k1, k2 = np.abs(curvature.kappa1), np.abs(curvature.kappa2)
    umbilic = (k1 - k2) < umbilic_tolerance * np.maximum(k1, 0.1 / diag)
    local = np.column_stack([np.cos(angle), np.sin(angle)])
    return LineField(angle=angle, direction=frames.to_world(local), umbilic=umbilic, aligned=aligned)
