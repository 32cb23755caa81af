"""Rows continued straight where the stripes turn away (``design/row_ends.py``, issue 34)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from ribbond.design.row_ends import MIN_EXTENSION, extend_ends, turned_extensions


def test_a_turn_shared_by_two_dashes_is_split_and_a_turn_at_a_rows_end_is_whole() -> None:
    # one row from 0 to 100: dashes [10, 25] and [60, 70]; the row turns on [30, 50] and on [80, 100]
    lo = np.array([0.0, 30.0, 50.0, 80.0])
    hi = np.array([30.0, 50.0, 80.0, 100.0])
    turned = np.array([False, True, False, True])
    A, B = np.array([10.0, 60.0]), np.array([25.0, 70.0])
    row = np.zeros(2, dtype=np.int64)
    f = np.array([0.8, 0.5])
    ext_lo, ext_hi = turned_extensions(lo, hi, turned, A, B, row, np.full(2, 100.0), np.zeros(2), f)
    # the 20 mm turn between them: half each, at each one's share f; the 20 mm at the row's end: all of it
    np.testing.assert_allclose(ext_hi, [0.8 * 10.0, 0.5 * 20.0])
    np.testing.assert_allclose(ext_lo, [0.0, 0.5 * 10.0])


def test_short_extensions_are_not_made() -> None:
    lo, hi = np.array([0.0, 20.0]), np.array([20.0, 21.0])
    ext_lo, ext_hi = turned_extensions(lo, hi, np.array([False, True]), np.array([5.0]), np.array([19.0]),
                                       np.zeros(1, dtype=np.int64), np.array([21.0]), np.array([0.0]),
                                       np.array([0.8]))
    assert ext_hi[0] == 0.0 and 0.8 * 1.0 < MIN_EXTENSION


def test_an_end_runs_straight_to_the_outline_and_stops_before_another_ribbon() -> None:
    inset = shapely.box(0.0, -20.0, 50.0, 20.0)
    shapely.prepare(inset)
    dash = np.array([[10.0, 0.0], [20.0, 0.0]])
    other = np.array([[40.0, -5.0], [40.0, 5.0]])                 # across the first one's way, at x = 40
    far = np.array([[10.0, 10.0], [20.0, 10.0]])                  # a row μ2 = 10 mm away: no obstacle
    out = extend_ends([dash, other, far], np.array([0.0, 0.0, 0.0]), np.array([100.0, 0.0, 40.0]),
                      np.full(3, 10.0), inset)
    # the first stops half a μ2 (5 mm) before the other ribbon; the third at the outline (x = 50)
    assert out[0][-1][0] == pytest.approx(35.0, abs=0.3) and out[0][-1][1] == pytest.approx(0.0)
    assert out[2][-1][0] == pytest.approx(50.0, abs=0.3)
    np.testing.assert_array_equal(out[1], other)
    # the start of a dash runs backward along its first segment
    back = extend_ends([dash], np.array([5.0]), np.array([0.0]), np.array([10.0]), inset)[0]
    np.testing.assert_allclose(back[0], [5.0, 0.0], atol=1e-9)


def test_two_extensions_that_meet_are_cut_where_they_meet() -> None:
    inset = shapely.box(-50.0, -50.0, 50.0, 50.0)
    a = np.array([[-20.0, 0.0], [-10.0, 0.0]])                    # pointing at each other along y = 0
    b = np.array([[20.0, 0.0], [10.0, 0.0]])
    out = extend_ends([a, b], np.zeros(2), np.full(2, 15.0), np.full(2, 4.0), inset)
    gap = out[1][-1][0] - out[0][-1][0]
    assert gap >= 2.0 - 1e-9                                      # half a μ2 apart at least
    assert out[0][-1][0] > -10.0 and out[1][-1][0] < 10.0          # both still extended
