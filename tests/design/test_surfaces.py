"""The scan-like generators of ``ribbond.design.surfaces`` (``irregular_grid``, ``irregular_disk``):
the same domain and boundary as the regular ones, every face counter-clockwise and of positive area,
interior vertices moved, irregular valences, and the same mesh for the same seed."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from ribbond.design import surfaces as S


def _signed_areas(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


@pytest.mark.parametrize("make, regular, area", [
    (lambda seed: S.irregular_grid(12, 8, seed), lambda: S.grid(12, 8), 1.0),
    (lambda seed: S.irregular_disk(6, seed), lambda: S.disk(6), None),
])
def test_a_scan_like_mesh_covers_the_regular_ones_domain(make, regular, area) -> None:
    P, F = make(3)
    P0, F0 = regular()
    assert len(P) == len(P0)
    assert np.all(_signed_areas(P, F) > 0)                          # CCW, none degenerate
    # the boundary stays where the regular mesh has it; the interior moves
    loop = igl.boundary_loop(F)
    assert np.array_equal(np.sort(loop), np.sort(igl.boundary_loop(F0)))
    assert np.array_equal(P[loop], P0[loop])
    inner = np.setdiff1d(np.arange(len(P)), loop)
    assert np.all(np.linalg.norm(P[inner] - P0[inner], axis=1) > 0)
    total = _signed_areas(P, F).sum()
    assert np.isclose(total, area if area is not None else _signed_areas(P0, F0).sum(), rtol=1e-12)
    valences = np.bincount(F.ravel(), minlength=len(P))[inner]
    assert len(np.unique(valences)) >= 3                             # not the regular mesh's valences
    same = make(3)
    assert all(np.array_equal(a, b) for a, b in zip((P, F), same))
    other = make(4)
    assert not np.array_equal(P, other[0])
