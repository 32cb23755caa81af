"""Kabsch registration and the deviation against known rigid motions and known offsets."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ribbond.deploy.compare import kabsch, registered_deviation, surface_deviation
from ribbond.design import surfaces


def test_kabsch_recovers_a_rigid_motion():
    rng = np.random.default_rng(0)
    P = rng.standard_normal((50, 3))
    R = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    t = np.array([4.0, -2.0, 9.0])
    Rf, tf = kabsch(P, P @ R.T + t)
    np.testing.assert_allclose(Rf, R, atol=1e-12)
    np.testing.assert_allclose(tf, t, atol=1e-12)
    assert np.linalg.det(Rf) == pytest.approx(1.0)


def test_kabsch_never_reflects():
    P = np.random.default_rng(1).standard_normal((20, 3))
    R, _ = kabsch(P, P * np.array([1.0, 1.0, -1.0]))     # a mirror image: the best rotation, not a reflection
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_kabsch_refuses_bad_shapes():
    with pytest.raises(ValueError, match="kabsch"):
        kabsch(np.zeros((2, 3)), np.zeros((2, 3)))


def test_deviation_of_a_moved_copy_is_zero_and_of_an_offset_is_the_offset():
    V, F = surfaces.cylinder_patch(radius=40.0, n_around=30, n_along=10)
    diag = np.linalg.norm(V.max(0) - V.min(0))
    R = Rotation.from_rotvec([0.2, 0.4, -0.3]).as_matrix()
    moved = V @ R.T + np.array([10.0, 0.0, -5.0])
    dev = surface_deviation(moved, V, V, F)
    assert dev.max_pct < 1e-9
    np.testing.assert_allclose(dev.V, V, atol=1e-9)
    # a coaxial cylinder 2 mm further out, registered by the vertex correspondence: each vertex
    # is 2 mm from the surface (the registration moves it by the mean offset only)
    n = np.column_stack([V[:, 0], V[:, 1], np.zeros(len(V))]) / 40.0
    out = V + 2.0 * n
    dev = surface_deviation(out, V, V, F)
    assert dev.diagonal == pytest.approx(diag)
    assert dev.as_dict().keys() == {"mean", "p99", "max"}
    assert dev.max_pct <= 100 * 2.0 / diag + 1e-9
    assert dev.mean_pct > 100 * 0.5 / diag        # the offset is not registered away


def test_registered_deviation_measures_heights_above_a_plane():
    """Points above a flat square, not moved (already registered): each distance is its height,
    or the distance to the nearest edge point where it lies outside the square."""
    V = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0], [0.0, 10.0, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    Y = np.array([[2.0, 3.0, 1.5], [5.0, 5.0, -0.25], [13.0, 5.0, 4.0]])
    d = registered_deviation(Y, V, F)
    np.testing.assert_allclose(d.distance, [1.5, 0.25, 5.0], rtol=1e-12)
    assert d.diagonal == pytest.approx(np.sqrt(200.0))
    assert d.mean_pct == pytest.approx(100 * (1.5 + 0.25 + 5.0) / 3 / np.sqrt(200.0))
    np.testing.assert_array_equal(d.V, Y)                         # not moved


def test_registered_deviation_refuses_bad_vertices():
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    F = np.array([[0, 1, 2]])
    with pytest.raises(ValueError, match="not finite"):
        registered_deviation(np.array([[0.0, np.nan, 0.0]]), V, F)
    with pytest.raises(ValueError, match=r"\(k, 3\)"):
        registered_deviation(np.zeros((2, 2)), V, F)
