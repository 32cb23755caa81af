"""Midpoint subdivision of the flat mesh: nothing moves, areas and windings are kept."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.refine import subdivide
from ribbond.design.ribbons import refinement_rounds
from ribbond.design.stripes import edge_topology, face_areas


def signed(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    a, b = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


@pytest.mark.parametrize("rounds", [0, 1, 2])
def test_subdivision_keeps_area_winding_and_positions(rounds: int) -> None:
    P, F = surfaces.disk(4)
    uv = P * 30.0
    sub = subdivide(F, len(uv), rounds)
    fine = sub.prolong(uv)
    assert len(sub.F) == len(F) * 4 ** rounds
    assert sub.rounds == rounds
    np.testing.assert_allclose(fine[: len(uv)], uv)                 # old vertices stay put
    assert np.all(signed(fine, sub.F) > 0)                          # winding kept
    per_parent = np.bincount(sub.parent, weights=face_areas(fine, sub.F), minlength=len(F))
    np.testing.assert_allclose(per_parent, face_areas(uv, F), rtol=1e-12)
    # still a disk: V − E + F = 1
    assert len(fine) - len(edge_topology(sub.F).edges) + len(sub.F) == 1


def test_prolongation_is_exact_for_linear_fields() -> None:
    UV, F = surfaces.grid(5, 4)
    sub = subdivide(F, len(UV), 2)
    fine = sub.prolong(UV)
    field = 3.0 * UV[:, 0] - 2.0 * UV[:, 1] + 0.5
    np.testing.assert_allclose(sub.prolong(field), 3.0 * fine[:, 0] - 2.0 * fine[:, 1] + 0.5, atol=1e-12)
    # each fine face lies inside its parent: its centroid has barycentric coordinates in [0, 1]
    c = fine[sub.F].mean(axis=1)
    T = UV[F[sub.parent]]
    M = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], axis=2)
    lam = np.linalg.solve(M, (c - T[:, 0])[..., None])[..., 0]
    assert np.all(lam >= -1e-12) and np.all(lam.sum(axis=1) <= 1 + 1e-12)


def test_refinement_rounds_follow_the_period_and_the_face_cap() -> None:
    UV, F = surfaces.grid(10, 10)
    uv = UV * 100.0                                   # edges 10 mm, diagonals ≈ 14.1 mm
    assert refinement_rounds(uv, F, 100.0, 0.3, 10**6) == 0
    assert refinement_rounds(uv, F, 20.0, 0.3, 10**6) == 2       # 14.1 / 4 ≤ 6 < 14.1 / 2
    assert refinement_rounds(uv, F, 20.0, 0.3, len(F) * 4) == 1  # capped by the face budget


def test_negative_rounds_are_refused() -> None:
    with pytest.raises(ValueError, match="rounds"):
        subdivide(np.array([[0, 1, 2]]), 3, -1)
