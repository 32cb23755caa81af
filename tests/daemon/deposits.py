"""What the simulator deposited, part by part of the programs (issue 16's resume tests).

A program's parts are its ``;TYPE:`` sections; each extruding move of a part is keyed by its start
and end (x, y) and its z, to 1 µm (the programs write 1 µm), and the simulator's deposited segments
(its executed extruding moves, in machine coordinates) are counted against those keys. The moves
come from ``tests/gcode/reader.py`` (Marlin's semantics, nothing from ribbond).
"""

from __future__ import annotations

import sqlite3
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.gcode.reader import read_gcode

Key = tuple[float, float, float, float, float]


def _key(x0: float, y0: float, x1: float, y1: float, z: float) -> Key:
    return (round(x0, 3), round(y0, 3), round(x1, 3), round(y1, 3), round(z, 3))


@dataclass(frozen=True)
class ProgramPart:
    kind: str                 # RIBBON, REGISTRATION, …
    label: str                # the ;TYPE: line
    moves: tuple[Key, ...]    # its extruding moves


def program_parts(text: str) -> list[ProgramPart]:
    """The ``;TYPE:`` sections of a program and their extruding moves, in print order."""
    lines = text.splitlines()
    part_of_line: list[int] = []
    labels: list[str] = []
    for raw in lines:
        if raw.strip().startswith(";TYPE:"):
            labels.append(raw.strip())
        part_of_line.append(len(labels) - 1)
    moves: list[list[Key]] = [[] for _ in labels]
    for m in read_gcode(text).extruding_moves():
        k = part_of_line[m.line - 1]
        if k >= 0 and m.moves_xy:
            moves[k].append(_key(m.start[0], m.start[1], m.end[0], m.end[1], m.end[2]))
    return [ProgramPart(label.split()[0][len(";TYPE:"):], label, tuple(mv)) for label, mv in zip(labels, moves)]


def executed(segments: list[dict[str, Any]], side: str) -> Counter[Key]:
    """How many times each move was executed on ``side`` of the frame."""
    return Counter(_key(s["x0"], s["y0"], s["x1"], s["y1"], s["z"]) for s in segments if s["side"] == side)


def outcome(part: ProgramPart, done: Counter[Key]) -> str:
    """``full`` (every move once), ``partial`` (some never, none twice), ``over`` (a move more than once),
    ``none`` (no move)."""
    counts = [done[k] for k in part.moves]
    if any(c > 1 for c in counts):
        return "over"
    if all(c == 1 for c in counts):
        return "full"
    return "partial" if any(counts) else "none"


def part_events(db: Path, job: str) -> list[dict[str, Any]]:
    """The store's part events of ``job`` (read-only, after the daemon stopped)."""
    conn = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        conn.row_factory = sqlite3.Row
        return [dict(r) for r in conn.execute("SELECT run, side, part, event, line FROM part_events "
                                              "WHERE job_id = ? ORDER BY seq", (job,))]
    finally:
        conn.close()


def integrity(db: Path) -> str:
    conn = sqlite3.connect(db)
    try:
        return "; ".join(str(r[0]) for r in conn.execute("PRAGMA integrity_check"))
    finally:
        conn.close()
