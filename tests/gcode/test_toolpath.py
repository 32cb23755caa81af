"""Ribbons to passes, the travel ordering and the time estimate, on cases worked out by hand."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import shapely

from ribbond.gcode.estimate import move_times
from ribbond.gcode.ordering import order_ribbons, tour_length
from ribbond.gcode.toolpath import layer_plan, line_plan, offset_polyline, ribbon_passes

# ---------------------------------------------------------------------------------------------
# passes


@pytest.mark.parametrize(("width", "nozzle", "lines"), [(1.5, 0.8, 2), (1.5, 0.4, 4), (0.8, 0.8, 1), (2.5, 0.8, 3)])
def test_lines_fill_the_ribbon_width(width: float, nozzle: float, lines: int) -> None:
    n, w = line_plan(width, nozzle)
    assert n == lines and n * w == pytest.approx(width)


@pytest.mark.parametrize(("tau", "layers"), [(0.2, 1), (0.3, 1), (0.31, 2), (0.6, 2), (0.61, 3), (1.6, 6)])
def test_layers_split_the_thickness_evenly(tau: float, layers: int) -> None:
    n, h = layer_plan(tau, 0.3)
    assert n == layers and n * h == pytest.approx(tau) and h <= 0.3 + 1e-12


def test_offset_of_a_bent_polyline_keeps_its_distance_from_both_legs() -> None:
    pts = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    off = offset_polyline(pts, 0.5)                     # to the left of travel
    np.testing.assert_allclose(off, [[0.0, 0.5], [9.5, 0.5], [9.5, 10.0]], atol=1e-12)
    line = shapely.LineString(pts)
    assert all(abs(line.distance(shapely.Point(p)) - 0.5) < 1e-12 for p in off)


def test_passes_snake_over_lines_and_layers_and_carry_the_ribbon_volume() -> None:
    pts = np.array([[0.0, 0.0], [7.0, 1.0], [15.0, 0.0]])
    rp = ribbon_passes(pts, 1.5, 0.5, 0.8, 0.3)         # 2 lines × 2 layers of 0.25
    assert len(rp.paths) == 4 and list(rp.layer) == [0, 0, 1, 1]
    assert rp.line_width == pytest.approx(0.75) and rp.layer_height == pytest.approx(0.25)
    # each pass starts where the previous one ended, or one line width across
    for a, b in zip(rp.paths[:-1], rp.paths[1:]):
        assert np.linalg.norm(a[-1] - b[0]) <= rp.line_width + 1e-9
    # an even number of passes comes back to the entry end
    assert np.linalg.norm(rp.exit - rp.entry) < 1.0
    # the rails sit at ±(w − line width)/2 from the centerline
    centre = shapely.LineString(pts)
    for path in rp.paths:
        d = [centre.distance(shapely.Point(p)) for p in path]
        np.testing.assert_allclose(d, 0.375, atol=0.02)
    length = centre.length
    volume = sum(rp.line_width * rp.layer_height * shapely.LineString(p).length for p in rp.paths)
    assert volume == pytest.approx(1.5 * 0.5 * length, rel=0.01)


def test_a_ribbon_needs_two_points() -> None:
    with pytest.raises(ValueError, match="at least two points"):
        ribbon_passes(np.array([[0.0, 0.0]]), 1.5, 0.5, 0.8, 0.3)


# ---------------------------------------------------------------------------------------------
# ordering


def segments_as_parts(segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Single-pass parts: entered at one end, left at the other (both directions)."""
    entry = np.stack([segs[:, 0], segs[:, 1]], axis=1)
    exit_ = np.stack([segs[:, 1], segs[:, 0]], axis=1)
    return entry, exit_


def brute_force(entry: np.ndarray, exit_: np.ndarray, start: np.ndarray) -> float:
    R = len(entry)
    best = np.inf
    for perm in itertools.permutations(range(R)):
        for flips in itertools.product([False, True], repeat=R):
            best = min(best, tour_length(np.array(perm), np.array(flips), entry, exit_, start))
    return best


def test_a_row_of_segments_is_printed_in_a_row() -> None:
    # five collinear 10 mm segments with 5 mm gaps, shuffled and half of them reversed
    segs = np.array([[[15.0 * k, 0.0], [15.0 * k + 10.0, 0.0]] for k in range(5)])
    rng = np.random.default_rng(1)
    shuffled = segs[rng.permutation(5)]
    shuffled[::2] = shuffled[::2, ::-1]
    entry, exit_ = segments_as_parts(shuffled)
    tour = order_ribbons(entry, exit_, np.array([-5.0, 0.0]))
    assert tour.travel_after == pytest.approx(5.0 + 4 * 5.0)      # from the start, then the gaps
    assert tour.travel_after <= tour.travel_before
    assert tour_length(tour.order, tour.reversed, entry, exit_, np.array([-5.0, 0.0])) == \
        pytest.approx(tour.travel_after)


@pytest.mark.parametrize("seed", range(4))
def test_ordering_is_near_the_optimum_on_small_random_cases(seed: int) -> None:
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 60, (6, 2))
    angle = rng.uniform(0, np.pi, 6)
    d = 5.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    segs = np.stack([centres - d, centres + d], axis=1)
    entry, exit_ = segments_as_parts(segs)
    start = np.zeros(2)
    tour = order_ribbons(entry, exit_, start)
    assert sorted(tour.order) == list(range(6))
    assert tour.travel_after == pytest.approx(tour_length(tour.order, tour.reversed, entry, exit_, start))
    assert tour.travel_after <= 1.15 * brute_force(entry, exit_, start) + 1e-9


def test_empty_ordering() -> None:
    tour = order_ribbons(np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), np.zeros(2))
    assert len(tour.order) == 0 and tour.travel_after == 0.0


# ---------------------------------------------------------------------------------------------
# time estimate


def test_a_long_move_takes_its_length_over_speed_plus_one_ramp() -> None:
    a, v, L = 1000.0, 50.0, 100.0
    t = move_times(np.zeros((1, 3)), np.array([[L, 0.0, 0.0]]), np.zeros(1), np.array([v]), a, 0.05, 25.0)
    # accelerate to v and back to rest: the ramps cost v/a more than cruising all the way
    assert t[0] == pytest.approx(L / v + v / a)


def test_a_short_move_never_reaches_its_feed_rate() -> None:
    a, L = 1000.0, 1.0
    t = move_times(np.zeros((1, 3)), np.array([[L, 0.0, 0.0]]), np.zeros(1), np.array([500.0]), a, 0.05, 25.0)
    assert t[0] == pytest.approx(2 * math.sqrt(L / a))        # triangle: up to the middle, down again


def test_collinear_moves_keep_their_speed_and_a_reversal_stops() -> None:
    a, v = 1000.0, 20.0
    start = np.array([[0.0, 0, 0], [10.0, 0, 0]])
    straight = move_times(start, np.array([[10.0, 0, 0], [20.0, 0, 0]]), np.zeros(2), np.full(2, v), a, 0.05, 25.0)
    assert straight.sum() == pytest.approx(20.0 / v + v / a)   # one ramp up, one down
    back = move_times(start, np.array([[10.0, 0, 0], [0.0, 0, 0]]), np.zeros(2), np.full(2, v), a, 0.05, 25.0)
    assert back.sum() == pytest.approx(2 * (10.0 / v + v / a))


def test_a_retraction_takes_its_length_over_the_retract_speed() -> None:
    t = move_times(np.zeros((1, 3)), np.zeros((1, 3)), np.array([-1.5]), np.array([25.0]), 1000.0, 0.05, 30.0)
    assert t[0] == pytest.approx(0.05)
