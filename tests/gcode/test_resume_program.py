"""The programs' sync points and the resumed program (issue 16), read back by the independent reader.

Every part (``;TYPE:`` section) ends retracted with an ``M400``: the command whose acknowledgement
proves the part executed. A program resumed at part k prints exactly the original's moves of parts
k… (same coordinates, same filament), after a prelude that homes, heats and brings the head, above
the fabric, to where the original program stood before part k.
"""

from __future__ import annotations

import math

import pytest

from ribbond.daemon.components.programs import program_parts, resumed_program
from ribbond.daemon.service import modal_state
from ribbond.printer.link import prepare_program

from .conftest import SaddleDesign
from .reader import read_gcode


def sections(text: str) -> list[list[str]]:
    """The raw lines of each ;TYPE: section (up to the next one, or the end)."""
    out: list[list[str]] = []
    for raw in text.splitlines():
        if raw.startswith(";TYPE:"):
            out.append([])
        if out:
            out[-1].append(raw)
    return out


def deposits(command: str) -> bool:
    """A G1 that moves in X or Y and pushes filament."""
    words = command.split()
    return words[0] == "G1" and any(w[0] in "XY" for w in words[1:]) and \
        any(w[0] == "E" and float(w[1:]) > 0 for w in words[1:])


def commands(lines: list[str]) -> list[str]:
    return [c for c in (raw.split(";", 1)[0].strip() for raw in lines) if c]


@pytest.mark.parametrize("side", ["front", "back"])
def test_every_part_ends_retracted_with_an_m400(saddle_design: SaddleDesign, side: str) -> None:
    text = saddle_design.texts[side]
    parts = sections(text)
    assert parts
    retract = saddle_design.profile.retraction.length
    for lines in parts:
        cmds = commands(lines)
        last_xy = max(i for i, c in enumerate(cmds) if deposits(c))
        sync = next(i for i, c in enumerate(cmds) if i > last_xy and c == "M400")
        between = read_gcode("\n".join(["G90", "M83"] + cmds[last_xy + 1:sync])).moves
        assert math.isclose(sum(m.e for m in between), -retract, abs_tol=1e-5), (lines[0], cmds[last_xy:sync + 1])


@pytest.mark.parametrize("side", ["front", "back"])
def test_program_parts_name_the_sync_and_the_first_extrusion(saddle_design: SaddleDesign, side: str) -> None:
    text = saddle_design.texts[side]
    lines = text.splitlines()
    stream = prepare_program(lines)
    parts = program_parts(lines)
    raw = sections(text)
    assert len(parts) == len(raw)
    for part, section in zip(parts, raw):
        assert section[0].startswith(f";TYPE:{part.kind}")
        cmds = commands(section)
        assert stream[part.begin:part.begin + len(cmds)] == cmds
        assert part.sync is not None and stream[part.sync] == "M400"
        assert part.first_e is not None and part.begin <= part.first_e < part.sync
        first = next(i for i, c in enumerate(cmds) if any(w.startswith("E") and float(w[1:]) > 0 for w in c.split()[1:]))
        assert part.first_e == part.begin + first


@pytest.mark.parametrize("side,start", [("front", 1), ("back", 2), ("back", -1)])
def test_a_resumed_program_prints_the_remaining_parts_exactly(saddle_design: SaddleDesign, side: str,
                                                              start: int) -> None:
    prof = saddle_design.profile
    text = saddle_design.texts[side]
    lines = text.splitlines()
    parts = program_parts(lines)
    start = start % len(parts)
    stream = prepare_program(lines)
    modal = modal_state(stream, parts[start].begin)
    resumed = resumed_program(lines, start, modal, prof, "test")
    original, again = read_gcode(text), read_gcode("\n".join(resumed))
    section_start = next(i for i, raw in enumerate(lines) if raw.startswith(";TYPE:") and
                         sum(1 for r in lines[:i] if r.startswith(";TYPE:")) == start) + 1
    want = [(m.start, m.end, m.e) for m in original.extruding_moves() if m.line > section_start]
    got = [(m.start, m.end, m.e) for m in again.extruding_moves()]
    assert got == want and got
    # the prelude: home, the heaters the program had set, then the head above the fabric at the
    # position before the part, then down to it, E reset
    head = commands(resumed[:resumed.index(next(r for r in resumed if r.startswith(";TYPE:")))])
    t = prof.temperatures
    assert head.index("G28") < head.index(f"M109 S{t.nozzle:.0f}") < head.index("G92 E0")
    assert "M83" in head and "G90" in head
    homed = again.homed_at[0]
    travel = [m for m in again.moves if m.line > homed and (m.moves_xy or m.kind == "z")]
    safe = prof.layers.fabric_z + prof.layers.safe_height
    assert travel[0].kind == "z" and travel[0].end[2] >= safe - 1e-9
    assert travel[1].end[:2] == pytest.approx((modal["x"], modal["y"])) and travel[1].end[2] >= safe - 1e-9
    assert travel[2].end == pytest.approx((modal["x"], modal["y"], modal["z"]))
    # no filament is pushed before the part's own moves: the prelude retracts, the part primes
    before_part = [m for m in again.moves if m.line <= len(head) + 1]
    assert sum(m.e for m in before_part) == pytest.approx(-prof.retraction.length)


def test_a_resumed_program_refuses_a_part_it_does_not_have(saddle_design: SaddleDesign) -> None:
    lines = saddle_design.texts["front"].splitlines()
    n = len(program_parts(lines))
    with pytest.raises(ValueError, match=f"the program has {n} parts"):
        resumed_program(lines, n, {"x": 1.0, "y": 1.0, "z": 1.0}, saddle_design.profile, "test")
