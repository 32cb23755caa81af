"""The subdivision hierarchy of a 1-to-4 split mesh (ribbond/design/subdivision.py), checked on
meshes subdivided here (libigl's upsample, our intake's refine) against their coarse meshes."""

import igl
import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.refine import refine
from ribbond.design.subdivision import coarser_level, subdivision_hierarchy


def test_one_split_gives_back_the_coarse_faces_and_midpoint_prolongation():
    V, F = surfaces.saddle(size=80.0, rings=6)
    fine_V, fine_F = igl.upsample(V, F, number_of_subdivs=1)
    G, S = coarser_level(fine_F, len(fine_V))
    assert np.array_equal(G, F)
    assert S.shape == (len(fine_V), len(V))
    # libigl put each new vertex at the middle of its edge: the prolongation of the coarse vertices
    np.testing.assert_allclose(S @ V, fine_V, rtol=0, atol=1e-12)
    # each row: the identity on a coarse vertex, two halves on a new one
    counts = np.diff(S.indptr)
    assert np.all(counts[: len(V)] == 1) and np.all(counts[len(V):] == 2)
    np.testing.assert_array_equal(np.asarray(S.sum(axis=1)).ravel(), 1.0)


def test_prolongation_is_exact_for_an_affine_flat_map_of_a_plane():
    V, F = surfaces.plane_disk(diameter=80.0, rings=5)
    fine = refine(V, F, 3)                                  # the intake's refinement, three rounds
    G, P, child = subdivision_hierarchy(fine.F, len(fine.V), len(F))
    assert np.array_equal(G, F) and P.shape == (len(fine.V), len(V))
    A = np.array([[1.3, 0.2], [-0.1, 1.1]])
    flat = fine.V[:, :2] @ A.T + [4.0, -2.0]                # an affine map of the plane
    np.testing.assert_allclose(P @ flat[: len(V)], flat, rtol=0, atol=1e-9)
    # the representative fine face lies inside its coarse face (positive barycentric coordinates)
    c = fine.V[fine.F[child]].mean(axis=1)
    bary = igl.barycentric_coordinates(c, V[G[:, 0]], V[G[:, 1]], V[G[:, 2]])
    assert np.all(bary > 0)


def test_hierarchy_stops_at_the_first_level_with_at_most_max_faces():
    V, F = surfaces.sphere_cap(radius=80.0, half_angle_deg=20, rings=6)
    fine_V, fine_F = igl.upsample(V, F, number_of_subdivs=3)
    G, P, _ = subdivision_hierarchy(fine_F, len(fine_V), 16 * len(F))
    assert len(G) == 16 * len(F) and P.shape[0] == len(fine_V)
    G, P, _ = subdivision_hierarchy(fine_F, len(fine_V), 16 * len(F) - 1)
    assert len(G) == 4 * len(F)
    assert subdivision_hierarchy(fine_F, len(fine_V), len(F) - 1) is None        # never that coarse
    assert subdivision_hierarchy(fine_F, len(fine_V), len(fine_F)) is None       # nothing to descend
    with pytest.raises(ValueError, match="max_faces"):
        subdivision_hierarchy(fine_F, len(fine_V), 0)


def test_meshes_that_are_not_a_split_are_refused():
    V, F = surfaces.saddle(size=80.0, rings=6)
    assert coarser_level(F, len(V)) is None                  # a mesh as generated
    fine_V, fine_F = igl.upsample(V, F, number_of_subdivs=1)
    rng = np.random.default_rng(1)
    assert coarser_level(fine_F[rng.permutation(len(fine_F))], len(fine_V)) is None   # faces shuffled
    assert coarser_level(fine_F[:-4], len(fine_V)) is None   # a group dropped: vertices left over
    # group 0's new vertex x (on its edge ab) renamed to group 1's, which lies on another edge
    x0, x1 = fine_F[2, 0], fine_F[6, 0]
    assert x0 != x1
    renamed = fine_F.copy()
    renamed[:4][renamed[:4] == x0] = x1
    assert coarser_level(renamed, len(fine_V)) is None
    assert coarser_level(fine_F[:, :2], len(fine_V)) is None


def test_a_new_vertex_named_for_two_different_edges_is_refused():
    """Group 1's new vertex on edge (1, 3) replaced by group 0's on edge (0, 1), the orphan dropped:
    the counts still fit a split (4 new vertices, 4 parent edges), only the parents disagree."""
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    F = np.array([[0, 1, 2], [2, 1, 3]])
    fine_V, fine_F = igl.upsample(V, F, number_of_subdivs=1)
    assert coarser_level(fine_F, len(fine_V)) is not None
    m01 = fine_F[0, 1]                                   # group 0: (a, x, z), x on edge ab = (0, 1)
    m13 = fine_F[6, 1]                                   # group 1: (x, y, z), y on edge bc = (1, 3)
    assert np.allclose(fine_V[m01], [0.5, 0.0, 0.0]) and np.allclose(fine_V[m13], [1.0, 0.5, 0.0])
    renamed = fine_F.copy()
    renamed[4:][renamed[4:] == m13] = m01
    renamed[renamed > m13] -= 1                          # the orphan m13 dropped, the rest re-indexed
    assert coarser_level(renamed, len(fine_V) - 1) is None
