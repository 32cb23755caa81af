"""Per-face isometric frames (§4.2, Fig. 4): each target triangle laid in the plane with its
edge x1 → x2 on the u-axis.

Tangent vectors of a face are written in its frame (e1, e2) with e1 along x1 → x2 and
e2 = n × e1, where n is the unit normal given by the winding. In that frame the triangle's
corners are X1 = (0, 0), X2 = (|x2 − x1|, 0), X3, counter-clockwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class FaceFrames:
    """Orthonormal frames and local coordinates of the faces of a triangle mesh.

    Attributes
    ----------
    e1, e2, n : (m, 3) unit vectors: the u-axis (along x1 → x2), the v-axis, the normal.
    X : (m, 3, 2) corner coordinates in the frame (X[:, 0] = 0, X[:, 1, 1] = 0).
    area : (m,) triangle areas.
    edge_inverse : (m, 2, 2) the inverse of [X2 − X1, X3 − X1], so that the Jacobian of a
        piecewise linear map is J = [x̄2 − x̄1, x̄3 − x̄1] @ edge_inverse (§4.2).
    """

    e1: np.ndarray
    e2: np.ndarray
    n: np.ndarray
    X: np.ndarray
    area: np.ndarray
    edge_inverse: np.ndarray

    def to_local(self, vectors: np.ndarray) -> np.ndarray:
        """(m, 3) tangent vectors → (m, 2) coordinates in each face's frame."""
        return np.column_stack([np.einsum("ij,ij->i", vectors, self.e1),
                                np.einsum("ij,ij->i", vectors, self.e2)])

    def to_world(self, local: np.ndarray) -> np.ndarray:
        """(m, 2) frame coordinates → (m, 3) tangent vectors."""
        return local[:, :1] * self.e1 + local[:, 1:2] * self.e2


def face_frames(V: np.ndarray, F: np.ndarray) -> FaceFrames:
    """The isometric frame of every face (§4.2).

    Parameters
    ----------
    V : (n, 3) float vertex positions.
    F : (m, 3) int faces.

    Raises
    ------
    ValueError
        if a face has (numerically) zero area, naming the first such face.
    """
    x1, x2, x3 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    a, b = x2 - x1, x3 - x1
    cross = np.cross(a, b)
    double_area = np.linalg.norm(cross, axis=1)
    len_a = np.linalg.norm(a, axis=1)
    bad = (double_area <= 0) | (len_a <= 0) | ~np.isfinite(double_area)
    if bad.any():
        raise ValueError(f"face {int(np.flatnonzero(bad)[0])} has zero area; "
                         f"{int(bad.sum())} such faces in all")
    n = cross / double_area[:, None]
    e1 = a / len_a[:, None]
    e2 = np.cross(n, e1)
    X = np.zeros((len(F), 3, 2))
    X[:, 1, 0] = len_a
    X[:, 2, 0] = np.einsum("ij,ij->i", b, e1)
    X[:, 2, 1] = np.einsum("ij,ij->i", b, e2)
    # [[X2u, X3u], [0, X3v]]^-1 in closed form (upper triangular).
    inv = np.zeros((len(F), 2, 2))
    inv[:, 0, 0] = 1.0 / len_a
    inv[:, 0, 1] = -X[:, 2, 0] / (len_a * X[:, 2, 1])
    inv[:, 1, 1] = 1.0 / X[:, 2, 1]
    return FaceFrames(e1=e1, e2=e2, n=n, X=X, area=0.5 * double_area, edge_inverse=inv)


def gradient_operator(F: np.ndarray, frames: FaceFrames, n_vertices: int) -> sp.csr_matrix:
    """The per-face gradient of a piecewise linear function, in each face's frame.

    Returns
    -------
    G : (2m, n) sparse matrix; for vertex values u (n,), ``(G @ u)[:m]`` is ∂u/∂X and
    ``(G @ u)[m:]`` is ∂u/∂Y of every face (X, Y the frame axes). For a flat map with vertex
    images UV (n, 2), ``G @ UV`` holds the Jacobians' columns: J[:, :, 0] = (G @ UV)[:m] and
    J[:, :, 1] = (G @ UV)[m:].
    """
    m = len(F)
    inv = frames.edge_inverse
    # ∇u = inv^T [u2 − u1, u3 − u1]: coefficients of u1, u2, u3 for each gradient component.
    c2, c3 = inv[:, 0, :], inv[:, 1, :]
    c1 = -(c2 + c3)
    vals = np.concatenate([np.column_stack([c1[:, k], c2[:, k], c3[:, k]]) for k in (0, 1)])
    rows = np.repeat(np.arange(2 * m), 3)
    cols = np.concatenate([F, F])
    return sp.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(2 * m, n_vertices))


def jacobians(G: sp.csr_matrix, UV: np.ndarray) -> np.ndarray:
    """(m, 2, 2) Jacobians of the piecewise linear map with vertex images UV (n, 2)."""
    g = G @ UV
    m = g.shape[0] // 2
    return np.stack([g[:m], g[m:]], axis=2)
