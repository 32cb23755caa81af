"""Rows along the outline where the rows run along it and the rim is bare (``ribbond.design.rim``).

A square outline, 60 mm, with the ribbon direction along x everywhere: its top and bottom edges run
along the rows, its left and right edges across them. Expected values come from Eq. 10's dash (a cell
of μ1 holds l_r of plastic) and the geometry of the square.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from ribbond.design.rim import RIM_CLEAR, RIM_FREE, rim_ribbons

W, L_R, MIN = 1.5, 15.0, 2.0
MU = (30.0, 6.0)                      # μ1, μ2: f1 = l_r / μ1 = 1/2
SIDE = 60.0
OUTLINE = shapely.box(0.0, 0.0, SIDE, SIDE)
INSET = OUTLINE.buffer(-0.5 * W, join_style="mitre")


def _rows(ys: list[float]) -> list[np.ndarray]:
    """Rows of dashes l_r long every μ1 along x at the heights ``ys``."""
    out = []
    for y in ys:
        for x0 in np.arange(2.0, SIDE - L_R, MU[0]):
            out.append(np.column_stack([np.linspace(x0, x0 + L_R, 31), np.full(31, y)]))
    return out


def _make(ribbons, short=True, kappa=lambda P: np.full(len(P), 0.02)):
    return rim_ribbons(INSET, ribbons, lambda P: np.tile([1.0, 0.0], (len(P), 1)), lambda P: np.tile(MU, (len(P), 1)),
                       kappa, L_R, W, MIN, short_at=lambda P: np.full(len(P), short))


def test_a_bare_rim_along_the_rows_gets_eq10_dashes_and_none_across_them():
    rim = _make(_rows([15.0, 21.0, 27.0, 33.0, 39.0, 45.0]))          # bare bands of 15 mm top and bottom
    assert len(rim.points) >= 2
    for P in rim.points:
        assert np.ptp(P[:, 1]) < 1e-6                                 # on a straight edge along the rows
        assert np.isclose(P[0, 1], 0.5 * W) or np.isclose(P[0, 1], SIDE - 0.5 * W)
        assert np.all(shapely.contains_xy(OUTLINE.buffer(1e-6), P[:, 0], P[:, 1]))
    ys = {round(float(P[0, 1]), 3) for P in rim.points}
    assert ys == {0.75, SIDE - 0.75}                                 # top and bottom, not the sides
    # Eq. 10: the edge (58.5 mm) is cut into round(58.5 / μ1) = 2 cells, each holding f1 = l_r / μ1 of its
    # length, centred; the dashes never fuse
    for y in ys:
        on = sorted((P for P in rim.points if np.isclose(P[0, 1], y)), key=lambda P: P[0, 0])
        assert len(on) == 2
        cell = (SIDE - W) / 2
        for k, P in enumerate(on):
            assert np.ptp(P[:, 0]) == pytest.approx(L_R / MU[0] * cell, abs=0.3)
            assert P[:, 0].mean() == pytest.approx(0.5 * W + (k + 0.5) * cell, abs=0.3)
    np.testing.assert_allclose(rim.kappa1, 0.02)
    np.testing.assert_allclose(rim.spacing, np.tile(MU, (len(rim.points), 1)))
    assert not rim.replaced.any()


def test_no_rim_where_the_plastic_is_not_short_or_a_row_is_near():
    assert _make(_rows([15.0, 21.0, 27.0, 33.0, 39.0, 45.0]), short=False).points == []
    near = RIM_FREE * MU[1] * 0.8                                      # the last rows closer than RIM_FREE μ2
    solid = [np.column_stack([np.linspace(0.75, SIDE - 0.75, 200), np.full(200, y)])
             for y in (0.75 + near, SIDE - 0.75 - near)]                # rows reaching the corners
    rim = _make(solid + _rows([9.0 + 6.0 * k for k in range(7)]))
    assert rim.points == []


def test_a_rim_dash_keeps_one_side():
    # κ1 changes sign at x = 18, inside the first cell's dash (about 8–22) were the edge one run
    rim = _make(_rows([21.0, 27.0, 33.0, 39.0]), kappa=lambda P: np.where(P[:, 0] < 18.0, 0.02, -0.02))
    assert len(rim.points) >= 4
    for P, k in zip(rim.points, rim.kappa1):
        inside = P[:, 0] < 18.0
        assert inside.all() or (~inside).all()
        assert np.sign(k) == (1 if inside.all() else -1)


def test_short_chords_by_the_rim_are_replaced_and_whole_ribbons_never():
    chord = np.column_stack([np.linspace(40.0, 43.0, 7), np.full(7, 1.5)])     # a 3 mm piece by the bottom edge
    rows = _rows([21.0, 27.0, 33.0, 39.0])
    rim = _make(rows + [chord])
    assert rim.replaced[-1] and not rim.replaced[:-1].any()
    for P in rim.points:                                            # no dash within RIM_CLEAR w of a whole ribbon
        d = np.min([np.min(np.linalg.norm(P[:, None] - r[None], axis=2)) for r in rows])
        assert d >= RIM_CLEAR * W - 1e-9


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="must be > 0"):
        rim_ribbons(INSET, [], lambda P: P, lambda P: P, lambda P: P[:, 0], 0.0, W, MIN)


def test_a_rim_dash_gives_way_to_a_whole_ribbon_near_it():
    # with μ2 = 4 mm a rim point is free 2.4 mm from a ribbon, but a dash keeps 2 ribbon widths (3 mm)
    mu = (30.0, 4.0)
    whole = np.column_stack([np.linspace(20.0, 40.0, 41), np.full(41, 0.75 + 2.7)])   # 2.7 mm above the rim
    rim = rim_ribbons(INSET, [whole] + _rows([21.0, 27.0, 33.0, 39.0]), lambda P: np.tile([1.0, 0.0], (len(P), 1)),
                      lambda P: np.tile(mu, (len(P), 1)), lambda P: np.full(len(P), 0.02), L_R, W, MIN,
                      short_at=lambda P: np.ones(len(P), dtype=bool))
    bottom = [P for P in rim.points if np.isclose(P[0, 1], 0.75)]
    assert bottom
    for P in bottom:
        assert np.min(np.linalg.norm(P[:, None] - whole[None], axis=2)) >= RIM_CLEAR * W - 1e-9
    assert not rim.replaced[0]
