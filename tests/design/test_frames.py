"""Per-face frames and the gradient operator (§4.2)."""

import igl
import numpy as np
import pytest
import scipy.sparse as sp

from ribbond.design import surfaces
from ribbond.design.frames import face_frames, gradient_operator, jacobians


def test_frames_are_isometric_with_the_first_edge_on_the_u_axis():
    V, F = surfaces.torus_patch(nu=12, nv=8)
    fr = face_frames(V, F)
    assert np.allclose(fr.X[:, 0], 0) and np.allclose(fr.X[:, 1, 1], 0)
    assert np.all(fr.X[:, 1, 0] > 0) and np.all(fr.X[:, 2, 1] > 0)      # counter-clockwise
    for i, j in [(0, 1), (1, 2), (2, 0)]:
        d3 = np.linalg.norm(V[F[:, i]] - V[F[:, j]], axis=1)
        d2 = np.linalg.norm(fr.X[:, i] - fr.X[:, j], axis=1)
        assert np.allclose(d2, d3, rtol=1e-12)
    assert np.allclose(np.einsum("ij,ij->i", fr.e1, fr.e2), 0)
    assert np.allclose(np.linalg.norm(fr.n, axis=1), 1)


def test_the_global_matrix_of_eq_9_is_the_cotangent_laplacian():
    V, F = surfaces.saddle(rings=6)
    fr = face_frames(V, F)
    G = gradient_operator(F, fr, len(V))
    L = G.T @ sp.diags(np.tile(fr.area, 2)) @ G
    assert abs(L + igl.cotmatrix(V, F)).max() < 1e-12


def test_jacobian_of_a_linear_map_of_a_plane():
    V, F = surfaces.plane_disk(rings=4)
    A = np.array([[1.2, 0.3], [-0.1, 1.4]])
    uv = V[:, :2] @ A.T + np.array([5.0, -2.0])
    fr = face_frames(V, F)
    J = jacobians(gradient_operator(F, fr, len(V)), uv)
    # In frame coordinates the map is A composed with the frame's axes (e1, e2 in the plane).
    B = np.stack([fr.e1[:, :2], fr.e2[:, :2]], axis=2)
    assert np.allclose(J, A @ B, atol=1e-12)


def test_zero_area_faces_are_refused_by_index():
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], float)
    F = np.array([[0, 1, 3], [0, 1, 2]])
    with pytest.raises(ValueError, match="face 1"):
        face_frames(V, F)
