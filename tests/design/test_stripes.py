"""Stripe patterns (KCPS15) on flat meshes: plane waves, line-field flips, graded and radial patterns."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse.linalg as spla

from ribbond.design import surfaces
from ribbond.design.stripes import (
    StripeSolver,
    chain_segments,
    cotangent_weights,
    edge_topology,
    vertex_average,
    vertex_line_field,
)


def square(n: int = 60, size: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    UV, F = surfaces.grid(n, n)
    return UV * size, F


def disk(rings: int = 40, radius: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    P, F = surfaces.disk(rings)
    return P * radius, F


def wrapped(x: np.ndarray, period: float) -> np.ndarray:
    """Positions modulo ``period`` as angles, so that a constant residue has zero spread."""
    return np.angle(np.exp(2j * np.pi * x / period))


def spread(angles: np.ndarray) -> float:
    """Largest angular distance of ``angles`` from their circular mean, radians."""
    mean = np.angle(np.mean(np.exp(1j * angles)))
    return float(np.max(np.abs(np.angle(np.exp(1j * (angles - mean))))))


# ---------------------------------------------------------------------------------------------
# set-up pieces


def test_edge_topology_counts_and_incidence() -> None:
    uv, F = square(7)
    top = edge_topology(F)
    # Euler for a disk: V − E + F = 1
    assert len(uv) - len(top.edges) + len(F) == 1
    assert np.all(top.edges[:, 0] < top.edges[:, 1])
    he_from = np.where(top.forward, top.edges[top.face_edges, 0], top.edges[top.face_edges, 1])
    assert np.array_equal(he_from, F)
    assert set(np.unique(top.faces_per_edge)) == {1, 2}
    assert np.sum(top.faces_per_edge == 1) == 4 * 7            # the square's boundary edges


def test_cotangent_weights_match_libigl() -> None:
    uv, F = disk(6)
    top = edge_topology(F)
    w = cotangent_weights(uv, F, top)
    L = igl.cotmatrix(np.column_stack([uv, np.zeros(len(uv))]), F)
    ref = np.asarray(L[top.edges[:, 0], top.edges[:, 1]]).ravel()
    # libigl's off-diagonal entry is ½ Σ cot; ours is raised to a small floor where that is negative
    np.testing.assert_allclose(w, np.maximum(ref, 1e-3), rtol=1e-10, atol=1e-12)


def test_vertex_line_field_ignores_the_sign_of_each_face_direction() -> None:
    uv, F = square(10)
    rng = np.random.default_rng(3)
    d = np.tile([np.cos(0.4), np.sin(0.4)], (len(F), 1)) * rng.choice([-1.0, 1.0], size=(len(F), 1))
    area = np.ones(len(F))
    X = vertex_line_field(F, d, area, len(uv))
    np.testing.assert_allclose(np.abs(X @ [np.cos(0.4), np.sin(0.4)]), 1.0, atol=1e-12)
    np.testing.assert_allclose(vertex_average(F, np.full(len(F), 2.5), area, len(uv)), 2.5)


def test_energy_matrix_is_symmetric_and_zero_on_a_plane_wave() -> None:
    uv, F = square(20)
    solver = StripeSolver(uv, F)
    X = np.tile([1.0, 0.0], (len(uv), 1))
    nu = np.full(len(uv), 2 * np.pi / 9.0)
    omega, flip = solver.edge_rotations(X, nu)
    A = solver.energy_matrix(omega, flip)
    assert abs(A - A.T).max() < 1e-12
    psi = np.exp(1j * nu * uv[:, 0])
    x = np.column_stack([psi.real, psi.imag]).ravel()
    assert x @ (A @ x) < 1e-18 * len(uv)
    y = np.random.default_rng(0).standard_normal(2 * len(uv))
    assert y @ (A @ y) > 0


# ---------------------------------------------------------------------------------------------
# patterns with known isolines


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 77.0])
def test_uniform_field_gives_straight_parallel_isolines_one_period_apart(angle_deg: float) -> None:
    uv, F = square(60)
    a = np.radians(angle_deg)
    d = np.array([np.cos(a), np.sin(a)])
    period = 10.0
    pattern = StripeSolver(uv, F).solve(np.tile(d, (len(uv), 1)), np.full(len(uv), 2 * np.pi / period))
    assert not pattern.singular.any()
    assert pattern.eigenvalue < 1e-8
    zero, half = pattern.isolines(0.0), pattern.isolines(np.pi)
    s0, s1 = wrapped(zero.points @ d, period), wrapped(half.points @ d, period)
    assert spread(s0) < 1e-6 and spread(s1) < 1e-6
    # the π isolines lie half a period from the 0 isolines
    gap = np.angle(np.exp(1j * (np.mean(s1) - np.mean(s0))))
    assert abs(abs(gap) - np.pi) < 1e-6
    # each polyline is one straight line across the square, perpendicular to d
    lines = chain_segments(len(zero.points), zero.segments, zero.segment_face)
    for p in range(lines.count):
        pts = zero.points[lines.nodes[lines.offsets[p]:lines.offsets[p + 1]]]
        assert np.ptp(pts @ d) < 1e-6
    # number of lines: the square's extent along d over the period (give or take one)
    extent = np.ptp(uv @ d)
    assert abs(lines.count - extent / period) <= 1.0


def test_flipped_representatives_do_not_change_the_pattern() -> None:
    """A line field's representatives are arbitrary: the isolines stay straight, one period apart
    (the pattern's global phase is free, so the offset of the lines is not compared)."""
    uv, F = square(40)
    d = np.array([np.cos(0.3), np.sin(0.3)])
    X = np.tile(d, (len(uv), 1))
    flips = np.random.default_rng(5).choice([-1.0, 1.0], size=(len(uv), 1))
    nu = np.full(len(uv), 2 * np.pi / 8.0)
    solver = StripeSolver(uv, F)
    a = solver.solve(X, nu).isolines(0.0)
    b = solver.solve(X * flips, nu).isolines(0.0)
    assert not solver.solve(X * flips, nu).singular.any()
    assert spread(wrapped(a.points @ d, 8.0)) < 1e-6
    assert spread(wrapped(b.points @ d, 8.0)) < 1e-6
    assert abs(len(a.points) - len(b.points)) <= 0.05 * len(a.points)


def test_the_global_phase_depends_neither_on_the_representatives_nor_on_rounding() -> None:
    """The phase is free, so the solver fixes it by its start: flipped representatives give the
    same lines, offset included; a uniform field has a line of phase 0 through the centroid; and a
    field along ±90°, whose representatives a 1e-9 nudge of the mesh turns over here and there (as
    a layout placed square in the frame has them), keeps its lines where they were."""
    uv, F = square(40)
    period = 8.0
    d = np.array([np.cos(0.3), np.sin(0.3)])
    nu = np.full(len(uv), 2 * np.pi / period)
    flips = np.random.default_rng(5).choice([-1.0, 1.0], size=(len(uv), 1))
    solver = StripeSolver(uv, F)
    a = solver.solve(np.tile(d, (len(uv), 1)), nu).isolines(0.0)
    b = solver.solve(np.tile(d, (len(uv), 1)) * flips, nu).isolines(0.0)
    centroid = uv.mean(axis=0)                       # the square's vertices are evenly spread
    assert spread(wrapped(np.concatenate([a.points, b.points]) @ d - centroid @ d, period)) < 1e-6
    # lines across y (the field along y): each vertex's representative from the averaged line field,
    # as the ribbons get theirs; a field off y by ±1e-12 turns them over here and there (rounding
    # does, on a layout placed square in the frame); the mesh itself nudged by 1e-9 of its size
    up = np.array([0.0, 1.0])
    offsets = []
    for seed, nudge in ((1, 0.0), (2, 1e-9)):
        moved = uv + nudge * 100.0 * np.random.default_rng(8).standard_normal(uv.shape)
        e = moved[F[:, 1:]] - moved[F[:, [0]]]
        area = 0.5 * np.abs(e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0])
        off = 1e-12 * np.random.default_rng(seed).standard_normal(len(F))
        X = vertex_line_field(F, np.column_stack([off, np.ones(len(F))]), area, len(moved))
        assert np.any(X[:, 1] < 0) and np.any(X[:, 1] > 0)    # the representatives disagree
        lines = StripeSolver(moved, F).solve(X, nu).isolines(0.0)
        offsets.append(wrapped(lines.points @ up, period))
    assert spread(np.concatenate(offsets)) < 1e-5


def test_the_pattern_is_the_smallest_eigenvector_where_the_next_is_close() -> None:
    """Concentric lines on a disk: the two smallest eigenvalues (each a complex pair) lie 2.5 %
    apart, so the Rayleigh quotient settles long before ψ does. The solver's ψ lies in the
    smallest eigenspace (ARPACK's, shift-invert), not in a mix of the two."""
    uv, F = disk(20)
    r = np.linalg.norm(uv, axis=1)
    X = np.column_stack([-uv[:, 1], uv[:, 0]]) / np.maximum(r, 1e-9)[:, None]
    X[r < 1e-9] = [1.0, 0.0]
    nu = np.full(len(uv), 2 * np.pi / 7.0)
    solver = StripeSolver(uv, F)
    pattern = solver.solve(X, nu)
    A = solver.energy_matrix(*solver.edge_rotations(X, nu))
    values, vectors = spla.eigsh(A, k=4, M=solver.mass, sigma=-1e-6)
    order = np.argsort(values)
    assert values[order[2]] < 1.05 * values[order[0]]                     # a close next pair
    x = np.column_stack([pattern.psi.real, pattern.psi.imag]).ravel()
    x /= np.sqrt(x @ (solver.mass @ x))
    smallest = vectors[:, order[:2]]                                       # M-orthonormal
    assert np.linalg.norm(smallest.T @ (solver.mass @ x)) > 0.99


def test_graded_frequency_across_the_lines_spaces_them_by_the_local_period() -> None:
    """Period P(x) = 6 + 0.04 x along x: the phase ∫ 2π/P dx is exact, so line k + 1 follows line k
    by the period at their midpoint (to second order in the gradient)."""
    uv, F = square(100, 120.0)
    period = 6.0 + 0.04 * uv[:, 0]
    pattern = StripeSolver(uv, F).solve(np.tile([1.0, 0.0], (len(uv), 1)), 2 * np.pi / period)
    iso = pattern.isolines(0.0)
    lines = chain_segments(len(iso.points), iso.segments, iso.segment_face)
    xs = np.sort([np.mean(iso.points[lines.nodes[lines.offsets[p]:lines.offsets[p + 1]], 0])
                  for p in range(lines.count)])
    gaps = np.diff(xs)
    expected = 6.0 + 0.04 * 0.5 * (xs[1:] + xs[:-1])
    np.testing.assert_allclose(gaps, expected, rtol=0.02)


def test_radial_field_gives_closed_circles_and_a_singularity_at_the_centre() -> None:
    uv, F = disk(50, 50.0)
    r = np.linalg.norm(uv, axis=1)
    X = uv / np.maximum(r, 1e-9)[:, None]
    X[r < 1e-9] = [1.0, 0.0]
    period = 8.0
    pattern = StripeSolver(uv, F).solve(X, np.full(len(uv), 2 * np.pi / period))
    centroids = uv[F].mean(axis=1)
    singular_r = np.linalg.norm(centroids[pattern.singular], axis=1)
    assert 1 <= pattern.singular.sum() and singular_r.max() < period
    iso = pattern.isolines(0.0)
    lines = chain_segments(len(iso.points), iso.segments, iso.segment_face)
    assert lines.closed.sum() >= 4
    for p in np.flatnonzero(lines.closed):
        nodes = lines.nodes[lines.offsets[p]:lines.offsets[p + 1]]
        assert nodes[0] == nodes[-1]
        radii = np.linalg.norm(iso.points[nodes], axis=1)
        assert np.ptp(radii) < 0.02 * period         # a circle about the centre
    rings = np.sort([np.linalg.norm(iso.points[lines.nodes[lines.offsets[p]]]) for p in np.flatnonzero(lines.closed)])
    np.testing.assert_allclose(np.diff(rings), period, rtol=0.02)


def test_half_turn_line_field_marks_the_faces_where_it_turns_over() -> None:
    """The line field at angle φ/2 (polar angle φ) has index ½ at the centre: no choice of
    representatives is consistent around it, and the faces where that shows are left out."""
    uv, F = disk(30, 50.0)
    phi = np.arctan2(uv[:, 1], uv[:, 0])
    X = np.column_stack([np.cos(phi / 2), np.sin(phi / 2)])
    pattern = StripeSolver(uv, F).solve(X, np.full(len(uv), 2 * np.pi / 10.0))
    assert pattern.singular.any()
    iso = pattern.isolines(0.0)
    assert not np.isin(iso.segment_face, np.flatnonzero(pattern.singular)).any()


def test_isolines_refuse_other_levels() -> None:
    uv, F = square(5)
    p = StripeSolver(uv, F).solve(np.tile([1.0, 0.0], (len(uv), 1)), np.full(len(uv), 1.0))
    with pytest.raises(ValueError, match="levels 0 and π"):
        p.isolines(1.0)


@pytest.mark.parametrize("bad", [np.nan, 0.0, -1.0])
def test_solve_refuses_bad_frequencies(bad: float) -> None:
    uv, F = square(5)
    nu = np.ones(len(uv))
    nu[3] = bad
    with pytest.raises(ValueError, match="frequency"):
        StripeSolver(uv, F).solve(np.tile([1.0, 0.0], (len(uv), 1)), nu)


# ---------------------------------------------------------------------------------------------
# chaining


def test_chain_segments_orders_paths_and_closes_loops() -> None:
    # a path 7-3-5-1-8 (given shuffled), a loop 2-4-6-9-2, node 0 alone
    path = [(7, 3), (5, 3), (5, 1), (8, 1)]
    loop = [(2, 4), (6, 4), (6, 9), (2, 9)]
    segs = np.array(path + loop)
    faces = np.arange(len(segs)) + 100
    order = np.random.default_rng(2).permutation(len(segs))
    pl = chain_segments(10, segs[order], faces[order])
    got = {tuple(pl.nodes[pl.offsets[p]:pl.offsets[p + 1]]): bool(pl.closed[p]) for p in range(pl.count)}
    assert got == {(7, 3, 5, 1, 8): False, (2, 4, 6, 9, 2): True} or \
        got == {(7, 3, 5, 1, 8): False, (2, 9, 6, 4, 2): True}
    # every link carries the face of its segment
    lookup = {frozenset(s): f for s, f in zip(map(tuple, segs), faces)}
    for p in range(pl.count):
        nodes = pl.nodes[pl.offsets[p]:pl.offsets[p + 1]]
        links = pl.link_face[pl.offsets[p]:pl.offsets[p + 1]]
        assert links[-1] == -1
        assert [lookup[frozenset((a, b))] for a, b in zip(nodes[:-1], nodes[1:])] == list(links[:-1])


def test_chain_segments_leaves_out_a_branching_crossing() -> None:
    # 0 would join three segments; the chain 3-4-5 is untouched
    pl = chain_segments(6, np.array([[0, 1], [0, 2], [0, 3], [3, 4], [4, 5]]), np.arange(5))
    got = [tuple(pl.nodes[pl.offsets[p]:pl.offsets[p + 1]]) for p in range(pl.count)]
    assert got == [(3, 4, 5)]


def test_anisotropic_weights_are_the_dirichlet_energy_of_the_tensor():
    from scipy.spatial import Delaunay

    from ribbond.design.stripes import anisotropic_weights, cotangent_weights, edge_topology, face_areas
    # a triangular lattice: equilateral faces, all weights positive
    jj, ii = np.mgrid[0:10, 0:12]
    uv = np.column_stack([(ii + 0.5 * (jj % 2)).ravel(), (jj * np.sqrt(3) / 2).ravel()]) * 2.0
    F = Delaunay(uv).simplices.astype(np.int64)
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[cw] = F[cw][:, [0, 2, 1]]
    F = F[face_areas(uv, F) > 1e-9]
    topo = edge_topology(F)
    t = np.tile([np.cos(0.3), np.sin(0.3)], (len(F), 1))
    # ratio 1: the cotangent weights
    assert np.allclose(anisotropic_weights(uv, F, topo, t, 1.0), cotangent_weights(uv, F, topo))
    # ratio r: w_ij = −Σ_faces A ∇φ_iᵀ D ∇φ_j, D = n nᵀ + r t tᵀ, with the hat functions'
    # gradients from the inverse of each face's edge matrix (an independent formula)
    r = 0.5
    w = anisotropic_weights(uv, F, topo, t, r)
    P = uv[F]
    E = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=1)         # rows: edges from corner 0
    G12 = np.linalg.inv(E).transpose(0, 2, 1)                             # ∇φ1, ∇φ2 as rows
    G = np.concatenate([-(G12[:, :1] + G12[:, 1:]), G12], axis=1)         # (m, 3, 2)
    n = np.column_stack([-t[:, 1], t[:, 0]])
    D = np.einsum("fi,fj->fij", n, n) + r * np.einsum("fi,fj->fij", t, t)
    K = face_areas(uv, F)[:, None, None] * np.einsum("fki,fij,flj->fkl", G, D, G)
    k = np.arange(3)
    expected = np.bincount(topo.face_edges.ravel(), weights=-K[:, k, (k + 1) % 3].ravel(),
                           minlength=len(topo.edges))
    assert np.allclose(w, np.maximum(expected, 1e-3), rtol=1e-9, atol=1e-12)
    assert (expected > 1e-3).mean() > 0.9          # the anisotropy is in the weights, not the floor
