"""The travel ordering is deterministic: a budget in moves, never in seconds (issue 35)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ribbond.gcode import ordering
from ribbond.gcode.ordering import order_ribbons, tour_length

from .conftest import PROGRAMS, build_saddle_design


def scattered_ribbons(R: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(R, 2, 2) entry and exit points of R straight ribbons scattered over a 150 mm square."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 150, (R, 2))
    b = a + rng.normal(0, 20, (R, 2))
    entry = np.stack([a, b], axis=1)
    return entry, entry[:, ::-1]


def test_same_ribbons_same_tour_whatever_the_clock(monkeypatch):
    entry, exit_ = scattered_ribbons(60, seed=1)
    first = order_ribbons(entry, exit_, np.zeros(2))
    # a clock that jumps an hour at every reading changes nothing: no decision reads the time
    import time
    now = [0.0]

    def jumping() -> float:
        now[0] += 3600.0
        return now[0]
    monkeypatch.setattr(time, "perf_counter", jumping)
    monkeypatch.setattr(time, "monotonic", jumping)
    second = order_ribbons(entry, exit_, np.zeros(2))
    assert np.array_equal(first.order, second.order) and np.array_equal(first.reversed, second.reversed)
    assert first.travel_after == second.travel_after


def test_a_larger_move_budget_never_gives_a_longer_tour():
    entry, exit_ = scattered_ribbons(40, seed=2)
    start = np.zeros(2)
    lengths = [order_ribbons(entry, exit_, start, move_budget=b).travel_after for b in (0, 10**5, 10**6, 10**7)]
    assert all(b <= a + 1e-9 for a, b in zip(lengths, lengths[1:]))
    tour = order_ribbons(entry, exit_, start)
    assert np.isclose(tour.travel_after, tour_length(tour.order, tour.reversed, entry, exit_, start))
    assert sorted(tour.order) == list(range(40))


def test_move_budget_below_zero_is_refused():
    entry, exit_ = scattered_ribbons(5, seed=3)
    with pytest.raises(ValueError, match="move_budget"):
        order_ribbons(entry, exit_, np.zeros(2), move_budget=-1)


def test_the_ordering_reads_no_clock():
    source = open(ordering.__file__, encoding="utf-8").read()
    assert not re.search(r"\bimport time\b|perf_counter|monotonic|datetime", source)


def test_two_compiles_of_one_mesh_write_byte_identical_programs(saddle_design, tmp_path):
    # the whole chain a second time (intake, field, flattening, ribbons, ordering, writing), in
    # another folder, against the module's compile of the same mesh
    first = saddle_design
    second = build_saddle_design(tmp_path)
    for name in PROGRAMS:
        a = (first.folder / f"{name}.gcode").read_bytes()
        b = (second.folder / f"{name}.gcode").read_bytes()
        assert a == b, f"{name}.gcode differs between two compiles"
        # and nothing in them is a time of day: no timestamp to strip before comparing
        assert not re.search(rb"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}", a)
