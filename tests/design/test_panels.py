"""The cut into panels (ribbond.panels.cut) and the seams (ribbond.panels.seams), against geometry."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.frames import face_frames
from ribbond.panels.cut import (bisect, boundary_loops, cut_weight, grid_partition, interior_edges, longest_axis,
                                panel_submesh, partition, seam_weights, spectral_embedding, straighten_seams)
from ribbond.panels.seams import (mark_fractions, outward_normals, points_at_fractions, polyline_length,
                                  seam_chains, seam_label)


def _rectangle(w: float, h: float, nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    UV, F = surfaces.grid(nu, nv)
    return np.column_stack([w * (UV[:, 0] - 0.5), h * (UV[:, 1] - 0.5), np.zeros(len(UV))]), F


def _graph(V: np.ndarray, F: np.ndarray):
    pairs, verts = interior_edges(F)
    m = len(F)
    weights = seam_weights(V, verts, pairs, np.tile([1.0, 0.0, 0.0], (m, 1)), np.zeros(m), np.zeros(m))
    return pairs, verts, weights, face_frames(V, F).area


def test_interior_edges_of_a_disk_count_as_euler_says():
    V, F = _rectangle(10, 5, 8, 4)
    pairs, verts = interior_edges(F)
    boundary = len(boundary_loops(F)[0])
    assert len(pairs) == (3 * len(F) - boundary) // 2          # each interior edge has two faces
    shared = np.array([len(set(F[a]) & set(F[b])) for a, b in pairs[:20]])
    assert np.all(shared == 2)
    assert all(set(v) <= set(F[a]) & set(F[b]) for v, (a, b) in zip(verts[:20], pairs[:20]))


def test_seam_weights_cost_twice_as_much_across_k1_where_k1_is_defined():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    verts = np.array([[0, 1], [0, 2]])
    pairs = np.array([[0, 1], [0, 1]])
    along_x = np.tile([1.0, 0, 0], (2, 1))
    w = seam_weights(V, verts, pairs, along_x, np.ones(2), np.zeros(2))
    assert w == pytest.approx([1.0, 2.0])                        # along k1: its length; across: twice
    umbilic = seam_weights(V, verts, pairs, along_x, np.zeros(2), np.zeros(2))
    assert umbilic == pytest.approx([1.0, 1.0])                  # no preferred direction at an umbilic


def test_three_panels_of_a_hemisphere_are_equal_gores_from_pole_to_rim():
    V, F = surfaces.sphere_cap(50.0, 90.0, rings=16)
    pairs, verts, weights, area = _graph(V, F)
    labels = partition(spectral_embedding(pairs, weights, area, 2), 3, pairs, weights, area)
    share = np.bincount(labels, weights=area) / area.sum()
    assert share == pytest.approx(np.full(3, 1 / 3), abs=0.03)   # the sphere's symmetry: equal thirds
    polar = np.degrees(np.arccos(np.clip(V[F].mean(axis=1)[:, 2] / 50.0, -1, 1)))
    for k in range(3):
        assert polar[labels == k].min() < 8 and polar[labels == k].max() > 85      # pole to rim: a gore
        _, Fp, _, _ = panel_submesh(V, F, labels, k)
        assert len(boundary_loops(Fp)) == 1
    assert cut_weight(labels, pairs, weights) < 1.3 * 3 * 50.0 * np.pi / 2      # three meridians (jagged)


def test_bisect_cuts_a_long_rectangle_across_its_length_into_equal_halves():
    V, F = _rectangle(200.0, 40.0, 40, 8)
    pairs, verts, weights, area = _graph(V, F)
    c = V[F].mean(axis=1)
    for across in (None, longest_axis(c, area, np.arange(len(F)))):
        labels = bisect(np.zeros(len(F), dtype=np.int64), 0, pairs, weights, area, across)
        assert np.bincount(labels, weights=area) == pytest.approx([4000.0, 4000.0], rel=0.05)
        cut = labels[pairs[:, 0]] != labels[pairs[:, 1]]
        seam_x = V[verts[cut]][..., 0]
        assert np.abs(seam_x).max() <= 10.0                       # across the middle, not along
        assert weights[cut].sum() == pytest.approx(40.0, rel=0.35)   # about the short side


def test_seam_chain_of_two_halves_is_the_cut_line_with_its_length():
    V, F = _rectangle(100.0, 40.0, 20, 8)
    labels = (V[F].mean(axis=1)[:, 0] > 0).astype(int)
    loops = []
    for k in range(2):
        _, Fp, vi, _ = panel_submesh(V, F, labels, k)
        loops.append(vi[boundary_loops(Fp)[0]])
    (chain,) = seam_chains(loops)
    assert chain.panels == (0, 1)
    assert np.allclose(V[chain.vertices, 0], 0.0)
    assert polyline_length(V[chain.vertices]) == pytest.approx(40.0)
    assert len(chain.vertices) == 9


def test_points_at_fractions_follow_the_measuring_polyline():
    P = np.array([[0.0, 0], [10, 0], [20, 0]])
    measure = np.array([[0.0, 0], [30, 0], [40, 0]])          # 3/4 of its length on the first segment
    got = points_at_fractions(P, measure, np.array([0.0, 0.375, 0.75, 1.0]))
    assert got[:, 0] == pytest.approx([0.0, 5.0, 10.0, 20.0])
    with pytest.raises(ValueError, match="no length"):
        points_at_fractions(P, np.zeros((3, 2)), np.array([0.5]))


def test_outward_normals_of_a_square_point_out():
    square = np.array([[0.0, 0], [10, 0], [10, 10], [0, 10]])
    n = outward_normals(square, np.array([[5.0, 0], [10, 5], [5, 10], [0, 5]]))
    assert n == pytest.approx(np.array([[0, -1], [1, 0], [0, 1], [-1, 0]]), abs=0.35)
    assert (n * np.array([[0, -1], [1, 0], [0, 1], [-1, 0]])).sum(axis=1).min() > 0.9


def test_marks_and_labels():
    assert mark_fractions(5.0, 20.0) == pytest.approx([0.5])
    assert mark_fractions(80.0, 20.0) == pytest.approx([0.25, 0.5, 0.75])     # every 20 mm, not at the ends
    assert [seam_label(i) for i in (0, 25, 26, 27)] == ["A", "Z", "AA", "AB"]


def test_straightened_gore_seams_are_meridians_on_the_sphere():
    V, F = surfaces.sphere_cap(50.0, 90.0, rings=16)
    pairs, verts, weights, area = _graph(V, F)
    labels = partition(spectral_embedding(pairs, weights, area, 2), 3, pairs, weights, area)
    X = straighten_seams(V, F, labels)
    sagitta = np.abs(np.linalg.norm(V[F].mean(axis=1), axis=1) - 50.0).max()   # the mesh's own distance
    assert np.abs(np.linalg.norm(X, axis=1) - 50.0).max() <= sagitta            # still on the (meshed) sphere
    loops = []
    for k in range(3):
        _, Fp, vi, _ = panel_submesh(X, F, labels, k)
        loops.append(vi[boundary_loops(Fp)[0]])
    for chain in seam_chains(loops):
        P = X[chain.vertices]
        before = polyline_length(V[chain.vertices])
        assert polyline_length(P) == pytest.approx(np.pi * 25.0, rel=0.01)     # a meridian: π r / 2
        assert before > 1.05 * polyline_length(P)                                # the zigzag it was
        normal = np.cross(P[0], P[-1])                                          # a meridian lies in a plane
        assert np.abs(P @ (normal / np.linalg.norm(normal))).max() < 1.0        # through the axis


def test_grid_partition_tiles_a_wide_rectangle_into_equal_cells():
    V, F = _rectangle(300.0, 200.0, 30, 20)
    pairs, verts, weights, area = _graph(V, F)
    labels = grid_partition(V[F].mean(axis=1), area, 2, 3, pairs, weights)
    assert np.bincount(labels, weights=area) == pytest.approx(np.full(6, 10000.0), rel=0.05)
    cut = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    x, y = V[verts[cut]][..., 0], V[verts[cut]][..., 1]
    on_x = np.isclose(x, 0.0, atol=1e-9).all(axis=1)                       # one cut across the long side
    on_y = (np.abs(np.abs(y) - 100.0 / 3) <= 7.0).all(axis=1)              # two across the short one (10 mm grid)
    assert (on_x | on_y).all()
    assert 800.0 <= weights[cut].sum() <= 1.2 * 800.0      # 200 + 2 × 300 mm straight, a little more on mesh edges


def test_fewest_panels_is_the_flat_area_over_the_frame():
    from ribbond.design.params import DesignParameters
    from ribbond.panels.project import fewest_panels
    from ribbond.gcode.profiles import FrameSpec
    frame = FrameSpec(center=(100.0, 100.0), size=(120.0, 120.0))
    p = DesignParameters()                               # σ1 ≥ 1.0, σ2 ≥ 1.3: flat area ≥ 1.3 × the target's
    assert fewest_panels(100.0 * 100.0 / (1.3 * 0.99), p, frame, 10.0) == 1     # exactly one 100 × 100 room
    assert fewest_panels(100.0 * 100.0 / (1.3 * 0.99) * 1.01, p, frame, 10.0) == 2
    assert fewest_panels(1e6, p, frame, 10.0) == int(np.ceil(1e6 * 1.3 * 0.99 / 1e4))
