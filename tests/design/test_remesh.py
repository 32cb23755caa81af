"""The uniform triangulation of the flat domain on which the stripe patterns are computed."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import shapely

from ribbond.design import surfaces
from ribbond.design.remesh import remesh_flat
from ribbond.design.ribbons import stripe_spacing
from ribbond.design.stripes import edge_topology, face_areas


def signed(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    a, b = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def l_shape(n: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """A concave L: the unit grid without its upper-right quarter, scaled to 120 mm."""
    UV, F = surfaces.grid(n, n)
    c = UV[F].mean(axis=1)
    F = F[~((c[:, 0] > 0.5) & (c[:, 1] > 0.5))]
    used = np.unique(F)
    index = np.full(len(UV), -1)
    index[used] = np.arange(len(used))
    return UV[used] * 120.0, index[F]


@pytest.mark.parametrize("shape", ["square", "disk", "L"])
def test_remesh_covers_the_domain_with_even_counter_clockwise_faces(shape: str) -> None:
    if shape == "square":
        UV, F = surfaces.grid(12, 12)
        uv = UV * 100.0
    elif shape == "disk":
        P, F = surfaces.disk(10)
        uv = P * 60.0
    else:
        uv, F = l_shape()
    loop = igl.boundary_loop(F)
    h = 3.0
    mesh = remesh_flat(uv, F, loop, h)
    assert np.all(signed(mesh.uv, mesh.F) > 0)
    outline = shapely.Polygon(uv[loop])
    # the new faces cover the outline (up to the chords of its resampled curved parts)
    assert abs(face_areas(mesh.uv, mesh.F).sum() - outline.area) < 0.01 * outline.area
    centroids = mesh.uv[mesh.F].mean(axis=1)
    assert shapely.contains_xy(outline, centroids[:, 0], centroids[:, 1]).all()
    top = edge_topology(mesh.F)
    lengths = np.linalg.norm(mesh.uv[top.edges[:, 1]] - mesh.uv[top.edges[:, 0]], axis=1)
    assert 0.8 * h < np.median(lengths) < 1.2 * h
    assert lengths.max() < 2.0 * h
    # every vertex is used
    assert np.array_equal(np.unique(mesh.F), np.arange(len(mesh.uv)))


def test_fields_are_carried_over_exactly_where_they_are_linear() -> None:
    UV, F = surfaces.grid(9, 7)
    uv = UV * np.array([90.0, 70.0])
    mesh = remesh_flat(uv, F, igl.boundary_loop(F), 4.0)
    field = np.column_stack([2.0 * uv[:, 0] - uv[:, 1], 0.5 + 0.1 * uv[:, 1]])
    got = mesh.vertex_values(field)
    np.testing.assert_allclose(got, np.column_stack([2.0 * mesh.uv[:, 0] - mesh.uv[:, 1],
                                                     0.5 + 0.1 * mesh.uv[:, 1]]), atol=1e-9)
    # each new face's centroid lies in the design face given as its parent
    c = mesh.uv[mesh.F].mean(axis=1)
    T = uv[F[mesh.parent]]
    M = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], axis=2)
    lam = np.linalg.solve(M, (c - T[:, 0])[..., None])[..., 0]
    assert np.all(lam >= -1e-9) and np.all(lam.sum(axis=1) <= 1 + 1e-9)


def test_corners_of_the_outline_are_kept() -> None:
    UV, F = surfaces.grid(5, 5)
    uv = UV * 100.0
    mesh = remesh_flat(uv, F, igl.boundary_loop(F), 7.0)
    for corner in ([0, 0], [100, 0], [100, 100], [0, 100]):
        assert np.min(np.linalg.norm(mesh.uv - corner, axis=1)) < 1e-9


def test_spacing_follows_the_period_unless_the_face_budget_is_exceeded() -> None:
    assert stripe_spacing(10.0, 10_000.0, 0.2, 10**6) == pytest.approx(2.0)
    coarse = stripe_spacing(10.0, 10_000.0, 0.2, 100)
    assert coarse > 2.0
    assert 10_000.0 / (np.sqrt(3) / 4 * coarse ** 2) == pytest.approx(100)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_bad_spacing_is_refused(bad: float) -> None:
    UV, F = surfaces.grid(3, 3)
    with pytest.raises(ValueError, match="spacing"):
        remesh_flat(UV, F, igl.boundary_loop(F), bad)


def test_a_straight_edge_that_wobbles_by_rounding_gives_no_slivers() -> None:
    # a flattening leaves straight outline edges straight only to ~1e-7 mm: three outline samples
    # nearly on a line must not become a face (its rest metric would be singular)
    UV, F = surfaces.grid(40, 20)
    uv = UV * np.array([120.0, 60.0])
    bottom = np.flatnonzero(UV[:, 1] == 0.0)
    uv[bottom, 1] += 1e-7 * np.sin(np.arange(len(bottom)) * 2.3)
    loop = igl.boundary_loop(F)
    mesh = remesh_flat(uv, F, loop, 2.5)
    tri = mesh.uv[mesh.F]
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    assert (signed(mesh.uv, mesh.F) / longest ** 2).min() > 0.05      # lattice faces: ≈ 0.43
    assert abs(face_areas(mesh.uv, mesh.F).sum() - 120.0 * 60.0) < 1e-3 * 120.0 * 60.0
