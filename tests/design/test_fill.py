"""The dashes that fill a layout's bare spots (ribbond.design.fill), on a synthetic flat domain whose
expectations come from Eq. 10: a uniform field along x, uniform σ, rows on one half only."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from ribbond.design.fill import FILL_CLEARANCE, fill_bare
from ribbond.design.params import spacing_for_sigma

L_R, W_R, S = 15.0, 1.5, 1.6
SIGMA1, SIGMA2 = 1.15, 1.4


def _square(size: float = 80.0, n: int = 21) -> tuple[np.ndarray, np.ndarray]:
    x = np.linspace(0.0, size, n)
    X, Y = np.meshgrid(x, x)
    uv = np.column_stack([X.ravel(), Y.ravel()])
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    F = np.concatenate([np.column_stack([a, a + 1, a + n + 1]), np.column_stack([a, a + n + 1, a + n])])
    return uv, F


def _fill(ribbons: list[np.ndarray], kappa: float = 0.02):
    uv, F = _square()
    mu1 = np.full(len(uv), float(spacing_for_sigma(np.array([SIGMA1]), L_R, S)[0]))
    mu2 = np.full(len(uv), float(spacing_for_sigma(np.array([SIGMA2]), W_R, S)[0]))
    direction = np.tile([1.0, 0.0], (len(F), 1))
    inset = shapely.box(0, 0, 80, 80).buffer(-0.5 * W_R)
    fill = fill_bare(uv, F, direction, mu1, mu2, np.full(len(uv), kappa), ribbons, inset, ribbon_length=L_R,
                     ribbon_width=W_R, min_length=2.0, min_gap=0.5 * W_R)
    return fill, mu1[0], mu2[0], inset


def _rows_on_the_right(mu2: float) -> list[np.ndarray]:
    ys = np.arange(0.5 * mu2, 80.0, mu2)
    return [np.array([[45.0, y], [78.0, y]]) for y in ys]


def test_bare_half_gets_dashes_of_eq_10s_share_along_the_field() -> None:
    _, _, mu2, _ = _fill([np.array([[0.0, 0.0], [1.0, 0.0]])])
    fill, mu1, mu2, inset = _fill(_rows_on_the_right(mu2))
    assert len(fill.points) > 10
    seg = np.array(fill.points)                                   # (k, 2, 2)
    d = seg[:, 1] - seg[:, 0]
    # along the field (x), of length f1 P with f1 = l_r/μ1 (Eq. 10) and P the lattice pitch (μ2 here)
    np.testing.assert_allclose(d[:, 1], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(d[:, 0]), L_R / mu1 * mu2, rtol=1e-9)
    np.testing.assert_allclose(fill.length, L_R / mu1 * mu2, rtol=1e-9)
    np.testing.assert_allclose(fill.spacing, np.tile([mu1, mu2], (len(seg), 1)), rtol=1e-9)
    # only where the rows leave the fabric bare, FILL_CLEARANCE μ2 from them, inside the inset
    rows = shapely.multilinestrings([shapely.linestrings(r) for r in _rows_on_the_right(mu2)])
    lines = shapely.linestrings(seg)
    assert np.all(shapely.distance(lines, rows) >= FILL_CLEARANCE * mu2 - 1e-9)
    assert np.all(shapely.contains(inset, lines))
    assert np.all(seg[:, :, 0].max(axis=1) < 45.0 - FILL_CLEARANCE * mu2 + 1e-9)
    assert np.all(fill.kappa1 == pytest.approx(0.02))


def test_a_complete_layout_gets_nothing() -> None:
    _, _, mu2, _ = _fill([np.array([[0.0, 0.0], [1.0, 0.0]])])
    ys = np.arange(0.5 * mu2, 80.0, mu2)
    rows = [np.array([[1.0, y], [79.0, y]]) for y in ys]          # every row, all the way
    fill, *_ = _fill(rows)
    assert fill.points == []


def test_an_empty_domain_is_refused() -> None:
    with pytest.raises(ValueError, match="μ2"):
        fill_bare(np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros(0),
                  np.zeros(0), [], shapely.box(0, 0, 1, 1), ribbon_length=L_R, ribbon_width=W_R, min_length=2.0,
                  min_gap=0.75)
