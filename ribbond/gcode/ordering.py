"""The order of the ribbons and the direction each is printed in, for short travel.

Each ribbon can be printed from either end; it is entered at one point and left at another (the
same end when its passes come back, the far end otherwise). The tour starts at a given point and
is open. A greedy nearest-neighbour tour over a k-d tree of the entry points (both directions of
every ribbon) is improved by 2-opt moves, each reversing a stretch of the tour and the direction
of every ribbon in it, and Or-opt moves, each moving one ribbon to the best gap in the better
direction, until neither helps; then the best tour is kicked (a double bridge within 30 positions,
drawn from a generator seeded with 0) and improved again, and kept if shorter (iterated local
search), for a budget counted in kicks, not seconds: the same ribbons give the same tour on every run
and every machine, so two compiles of one design write the same programs byte for byte. The gains of
all moves from one position are computed at once (prefix sums of the link lengths in both directions
for 2-opt).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class Tour:
    """Order (R,) of the ribbons, whether each is reversed (R,), and travel lengths, mm."""

    order: np.ndarray
    reversed: np.ndarray
    travel_before: float
    travel_after: float
    improvements: int


def tour_length(order: np.ndarray, rev: np.ndarray, entry: np.ndarray, exit_: np.ndarray,
                start: np.ndarray) -> float:
    """Travel of the tour: from ``start`` to the first entry, then exit to entry.

    order : (R,) ribbons in tour order; rev : (R,) per ribbon, True when printed reversed.
    entry, exit_ : (R, 2, 2) the entry and exit points of each ribbon, forward [:, 0] and reversed [:, 1].
    """
    if len(order) == 0:
        return 0.0
    d = rev[order].astype(int)
    e_in, e_out = entry[order, d], exit_[order, d]
    return float(np.linalg.norm(e_in[0] - start) + np.linalg.norm(e_in[1:] - e_out[:-1], axis=1).sum())


def _greedy(entry: np.ndarray, exit_: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R = len(entry)
    points = entry.reshape(-1, 2)                      # index 2 r + d: ribbon r in direction d
    tree = cKDTree(points)
    visited = np.zeros(R, dtype=bool)
    order = np.empty(R, dtype=np.int64)
    rev = np.zeros(R, dtype=bool)
    here = np.asarray(start, dtype=float)
    for step in range(R):                              # one step per ribbon, not per vertex
        k = min(8, 2 * R)
        while True:
            _, idx = tree.query(here, k=k)
            idx = np.atleast_1d(idx)
            free = idx[(idx < 2 * R) & ~visited[np.minimum(idx, 2 * R - 1) // 2]]
            if len(free) or k >= 2 * R:
                break
            k = min(2 * k, 2 * R)
        pick = int(free[0])
        r, d = divmod(pick, 2)
        order[step], rev[r] = r, bool(d)
        visited[r] = True
        here = exit_[r, d]
    return order, rev


def _two_opt_sweep(order: np.ndarray, rev: np.ndarray, entry: np.ndarray, exit_: np.ndarray,
                   start: np.ndarray) -> tuple[int, int]:
    """One pass of 2-opt over the tour positions (in place); the moves made and the moves weighed."""
    R = len(order)
    moves = 0
    for i in range(-1, R - 1):                         # reverse tour[i + 1 .. j]; i = −1: from the start
        d = rev[order].astype(int)
        e_in, e_out = entry[order, d], exit_[order, d]          # (R, 2) as the tour has it
        f_in, f_out = entry[order, 1 - d], exit_[order, 1 - d]  # if the ribbon were turned
        fwd = np.linalg.norm(e_in[1:] - e_out[:-1], axis=1)     # link k -> k+1 as is
        bwd = np.linalg.norm(f_in[:-1] - f_out[1:], axis=1)     # link k+1 -> k, both turned
        cf = np.concatenate([[0.0], np.cumsum(fwd)])
        cb = np.concatenate([[0.0], np.cumsum(bwd)])
        j = np.arange(i + 1, R)
        prev_out = start if i < 0 else e_out[i]
        old_head = np.linalg.norm(e_in[i + 1] - prev_out)
        new_head = np.linalg.norm(f_in[j] - prev_out, axis=1)
        nxt = np.minimum(j + 1, R - 1)
        has_next = j + 1 < R
        old_tail = np.where(has_next, np.linalg.norm(e_in[nxt] - e_out[j], axis=1), 0.0)
        new_tail = np.where(has_next, np.linalg.norm(e_in[nxt] - f_out[i + 1], axis=1), 0.0)
        gain = old_head + old_tail + (cf[j] - cf[i + 1]) - (new_head + new_tail + (cb[j] - cb[i + 1]))
        best = int(np.argmax(gain))
        if gain[best] > 1e-9:
            jj = j[best]
            seg = order[i + 1: jj + 1]
            rev[seg] = ~rev[seg]
            order[i + 1: jj + 1] = seg[::-1]
            moves += 1
    return moves, R * (R + 1) // 2                             # reversals weighed: i < j


def _or_opt_sweep(order: np.ndarray, rev: np.ndarray, entry: np.ndarray, exit_: np.ndarray,
                  start: np.ndarray) -> tuple[int, int]:
    """One pass of Or-opt (in place): move single ribbons to the best gap, in the better direction;
    the moves made and the moves weighed."""
    R = len(order)
    moves = 0
    if R < 3:
        return 0, 0
    for pos in range(R):
        d = rev[order].astype(int)
        e_in, e_out = entry[order, d], exit_[order, d]
        r = order[pos]
        prev_out = start if pos == 0 else e_out[pos - 1]
        removal = np.linalg.norm(e_in[pos] - prev_out)
        if pos + 1 < R:
            removal += np.linalg.norm(e_in[pos + 1] - e_out[pos]) - np.linalg.norm(e_in[pos + 1] - prev_out)
        # the tour without r: gaps after position k (k = −1: from the start), links out_k -> in_{k+1}
        keep = np.delete(np.arange(R), pos)
        outs = np.vstack([start[None, :], e_out[keep]])           # (R, 2): before each gap
        ins = np.vstack([e_in[keep], np.full((1, 2), np.nan)])      # after each gap (none at the end)
        link = np.where(np.isnan(ins[:, 0]), 0.0, np.linalg.norm(ins - outs, axis=1))
        best_cost, best_gap, best_dir = np.inf, -1, 0
        for dd in (0, 1):
            a, b = entry[r, dd], exit_[r, dd]
            tail = np.where(np.isnan(ins[:, 0]), 0.0, np.linalg.norm(np.nan_to_num(ins) - b, axis=1))
            cost = np.linalg.norm(outs - a, axis=1) + tail - link
            k = int(np.argmin(cost))
            if cost[k] < best_cost:
                best_cost, best_gap, best_dir = float(cost[k]), k, dd
        if best_cost < removal - 1e-9:
            rest = order[keep]
            order[:] = np.concatenate([rest[:best_gap], [r], rest[best_gap:]])
            rev[r] = bool(best_dir)
            moves += 1
    return moves, 2 * R * R                                    # R ribbons × R gaps × 2 directions


def _local_search(order: np.ndarray, rev: np.ndarray, entry: np.ndarray, exit_: np.ndarray,
                  start: np.ndarray, max_sweeps: int) -> tuple[int, int]:
    """2-opt and Or-opt sweeps (in place) until neither improves, at most ``max_sweeps`` of each
    (a bound that a tour of R ribbons never reaches in practice, so that the search always ends);
    the moves made and the moves weighed."""
    total = weighed = 0
    for _ in range(max_sweeps):
        moved, w2 = _two_opt_sweep(order, rev, entry, exit_, start)
        moved_or, w3 = _or_opt_sweep(order, rev, entry, exit_, start)
        total, weighed = total + moved + moved_or, weighed + w2 + w3
        if not moved + moved_or:
            break
    return total, weighed


#: The default budget of the iterated local search: candidate moves weighed (2-opt reversals and
#: Or-opt insertions); a kick and its descent weigh a few R² of them. 0.1-3.4 s of CPU for the
#: bench designs (12-150 ribbons), whose tours it makes no longer than the median of five runs of
#: the former 1 s time budget (bench/gcode.py; docs/benchmarks.md, "Print programs").
MOVE_BUDGET = 5_000_000
#: It stops earlier after this many kicks in a row without a shorter tour, or R of them if more.
IDLE_KICKS = 20
#: A cap on the sweeps of one descent; it ends by itself long before (each sweep shortens the tour).
MAX_SWEEPS = 1000


def order_ribbons(entry: np.ndarray, exit_: np.ndarray, start: np.ndarray,
                  move_budget: int = MOVE_BUDGET) -> Tour:
    """Order the ribbons and choose their directions for short travel.

    Deterministic: the budget counts candidate moves, never time, so the same input gives the
    same tour on every run and machine.

    Parameters
    ----------
    entry, exit_ : (R, 2, 2) entry and exit points of each ribbon printed forward ([:, 0]) and
        reversed ([:, 1]), mm.
    start : (2,) where the nozzle is before the first ribbon.
    move_budget : no new kick of the iterated local search once this many candidate moves have
        been weighed (a descent is always finished; 0: the greedy tour improved by 2-opt and
        Or-opt to a local optimum, no kick); it stops earlier after max(IDLE_KICKS, R) kicks in
        a row that found no shorter tour.
    """
    if move_budget < 0:
        raise ValueError(f"move_budget must be ≥ 0, got {move_budget}")
    R = len(entry)
    identity = np.arange(R)
    before = tour_length(identity, np.zeros(R, dtype=bool), entry, exit_, start)
    if R == 0:
        return Tour(identity, np.zeros(0, dtype=bool), 0.0, 0.0, 0)
    order, rev = _greedy(entry, exit_, start)
    improvements, weighed = _local_search(order, rev, entry, exit_, start, MAX_SWEEPS)
    best = tour_length(order, rev, entry, exit_, start)
    rng = np.random.default_rng(0)
    idle = 0
    while R >= 8 and weighed < move_budget and idle < max(IDLE_KICKS, R):   # stop when kicks stop paying
        idle += 1
        cand_order, cand_rev = order.copy(), rev.copy()
        lo = int(rng.integers(1, R - 3))                     # a local kick: within 30 positions
        a, b, c = np.sort(rng.choice(np.arange(lo, min(lo + 30, R)), size=3, replace=False))
        cand_order[:] = np.concatenate([order[:a], order[c:], order[b:c], order[a:b]])
        moves, w = _local_search(cand_order, cand_rev, entry, exit_, start, MAX_SWEEPS)
        weighed += w
        length = tour_length(cand_order, cand_rev, entry, exit_, start)
        if length < best - 1e-9:
            order[:], rev[:], best = cand_order, cand_rev, length
            improvements += moves + 1
            idle = 0
    after = tour_length(order, rev, entry, exit_, start)
    return Tour(order=order, reversed=rev, travel_before=before, travel_after=after,
                improvements=improvements)
