"""``RunProofs`` (``printer/proof.py``), the bookkeeping of proofs that commands have run on firmware
whose ``ok`` only says a line was received (Repetier). Commands run in order, so an ``M114``'s report
proves every line received before it, and an idle ``wait`` every line received (issue 35: the run
proof's survivors: two ``M114`` outstanding, a line needing proof right after an ``M114``)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from ribbond.printer.proof import RunProofs


@dataclass(frozen=True)
class Line:
    number: int
    command: str


def receive(proofs: RunProofs[Line], *lines: tuple[int, str, bool]) -> list[Line]:
    out = []
    for number, command, needs in lines:
        line = Line(number, command)
        proofs.received(line, needs_proof=needs)
        out.append(line)
    return out


def test_a_report_proves_the_lines_before_its_query_and_not_after() -> None:
    proofs: RunProofs[Line] = RunProofs()
    a, _query, b = receive(proofs, (1, "G1 X1", True), (2, "M114", False), (3, "G1 X2", True))
    assert proofs.oldest_unproven == a
    assert proofs.position_reported() == [a]
    assert proofs.oldest_unproven == b                       # received after the query: not proven by it
    assert proofs.position_reported() == []                  # no query left: a stray report proves nothing
    assert proofs.oldest_unproven == b


def test_two_queries_outstanding_are_answered_in_order() -> None:
    proofs: RunProofs[Line] = RunProofs()
    a, _, b, _, c = receive(proofs, (1, "G1 X1", True), (2, "M114", False), (3, "M400", True), (4, "M114", False),
                            (5, "G1 X3", True))
    assert proofs.position_reported() == [a]                 # the first report is the first M114's
    assert proofs.position_reported() == [b]                 # the second, the second's
    assert proofs.oldest_unproven == c and proofs.position_reported() == []


def test_a_line_needing_proof_right_after_a_query() -> None:
    proofs: RunProofs[Line] = RunProofs()
    _, after = receive(proofs, (7, "M114", False), (8, "M400", True))
    assert proofs.position_reported() == []                  # the M114 ran before line 8
    assert proofs.oldest_unproven == after
    receive(proofs, (9, "M114", False))
    assert proofs.position_reported() == [after]


def test_a_query_that_itself_needs_proof_is_proven_by_its_own_report() -> None:
    proofs: RunProofs[Line] = RunProofs()
    (query,) = receive(proofs, (3, "m114 ", True))           # Marlin reads commands case-insensitively
    assert proofs.position_reported() == [query] and proofs.oldest_unproven is None


@pytest.mark.parametrize("command", ["M1140", "G1 X1 ; M114", "", "M11"])
def test_only_an_m114_is_a_position_query(command: str) -> None:
    proofs: RunProofs[Line] = RunProofs()
    (line,) = receive(proofs, (1, command, True))
    assert proofs.position_reported() == [] and proofs.oldest_unproven == line


def test_idle_proves_every_line_received_and_drops_the_queries_it_covers() -> None:
    proofs: RunProofs[Line] = RunProofs()
    a, _, b, _, c = receive(proofs, (1, "G1 X1", True), (2, "M114", False), (3, "G1 X2", True), (4, "M114", False),
                            (5, "G1 X3", True))
    assert proofs.idle(3) == [a, b]
    assert proofs.oldest_unproven == c
    assert proofs.position_reported() == []                  # the next report is the 4th line's M114: proves none
    assert proofs.idle(5) == [c] and proofs.oldest_unproven is None


def test_idle_through_a_query_exactly_drops_it() -> None:
    proofs: RunProofs[Line] = RunProofs()
    receive(proofs, (1, "M114", False))
    (later,) = receive(proofs, (2, "G1 X1", True))
    assert proofs.idle(1) == []
    assert proofs.position_reported() == []                  # the query at 1 was covered by the wait
    assert proofs.oldest_unproven == later


def test_clear_returns_the_unproven_and_forgets_the_queries() -> None:
    proofs: RunProofs[Line] = RunProofs()
    a, _, b = receive(proofs, (1, "G1 X1", True), (2, "M114", False), (3, "G1 X2", True))
    assert proofs.clear() == [a, b]
    assert proofs.oldest_unproven is None and proofs.position_reported() == [] and proofs.clear() == []


def test_after_idle_the_next_report_is_the_next_querys() -> None:
    proofs: RunProofs[Line] = RunProofs()
    _, line, _ = receive(proofs, (3, "M114", False), (4, "G1 X1", True), (5, "M114", False))
    assert proofs.idle(3) == []                              # the M114 at 3 has run (its report was lost)
    assert proofs.position_reported() == [line]              # so this report is 5's: line 4 ran
