"""Stitch marks on a panel's seam allowance (issue 26): where two panels are pinned mark to mark.

A surface cut into panels is sewn back along seams. Each seam line carries marks at matching points
on both panels; a mark is printed on the front as one-layer lines:

- the **tick**, from the seam-line point ``at`` outward along the unit normal ``outward`` by
  ``tick_length``: its outer end is on the cutting line (``tick_length`` is the seam allowance);
- the **label** (``"A1"``: the seam's letter and the mark's number) in a single-stroke font of its
  own (``GLYPHS``), beside the tick, inside the allowance (between the seam line and the cutting
  line). The label's up is ``-outward`` (towards the panel), so a person standing outside the panel's
  edge, looking at the panel, reads it the right way up; it runs to the reader's right of the tick.

A glyph is drawn in a cell of ``CELL_W`` × ``CELL_H`` units (x to the right, y up, baseline y = 0);
a text of height h scales a unit to h / ``CELL_H`` and advances ``ADVANCE`` units per character.
Everything here is a pure function of arrays; lengths are mm in front-side print coordinates.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..design.format import StitchMark

#: A glyph's cell, units (x 0..CELL_W to the right, y 0..CELL_H up from the baseline).
CELL_W, CELL_H = 4.0, 6.0
#: From one character's left edge to the next one's, units (2 units of space between cells).
ADVANCE = 6.0
#: Default text height as a fraction of the tick's length (the seam allowance).
TEXT_FRACTION = 0.4
#: Room between the tick and the label's first cell, as a fraction of the text height.
TEXT_GAP = 0.35
#: Largest tolerated deviation of ``outward`` from unit length.
UNIT_TOLERANCE = 1e-6

_O = ((1, 0), (0, 1), (0, 5), (1, 6), (3, 6), (4, 5), (4, 1), (3, 0), (1, 0))
_P = ((0, 0), (0, 6), (3, 6), (4, 5), (4, 4), (3, 3), (0, 3))
_C = ((4, 5), (3, 6), (1, 6), (0, 5), (0, 1), (1, 0), (3, 0), (4, 1))

#: Each character's strokes: polylines of (x, y) in cell units.
_GLYPH_TABLE: dict[str, tuple[tuple[tuple[float, float], ...], ...]] = {
    "A": (((0, 0), (0, 4), (2, 6), (4, 4), (4, 0)), ((0, 3), (4, 3))),
    "B": (((0, 0), (0, 6), (3, 6), (4, 5), (4, 4), (3, 3), (0, 3)), ((3, 3), (4, 2), (4, 1), (3, 0), (0, 0))),
    "C": (_C,),
    "D": (((0, 0), (0, 6), (2, 6), (4, 4), (4, 2), (2, 0), (0, 0)),),
    "E": (((4, 6), (0, 6), (0, 0), (4, 0)), ((0, 3), (3, 3))),
    "F": (((4, 6), (0, 6), (0, 0)), ((0, 3), (3, 3))),
    "G": (_C[:-1] + ((4, 1), (4, 3), (2, 3)),),
    "H": (((0, 0), (0, 6)), ((4, 0), (4, 6)), ((0, 3), (4, 3))),
    "I": (((1, 6), (3, 6)), ((2, 6), (2, 0)), ((1, 0), (3, 0))),
    "J": (((4, 6), (4, 1), (3, 0), (1, 0), (0, 1)),),
    "K": (((0, 0), (0, 6)), ((4, 6), (0, 3), (4, 0))),
    "L": (((0, 6), (0, 0), (4, 0)),),
    "M": (((0, 0), (0, 6), (2, 3), (4, 6), (4, 0)),),
    "N": (((0, 0), (0, 6), (4, 0), (4, 6)),),
    "O": (_O,),
    "P": (_P,),
    "Q": (_O, ((2.5, 1.5), (4, 0))),
    "R": (_P, ((2, 3), (4, 0))),
    "S": (((4, 5), (3, 6), (1, 6), (0, 5), (0, 4), (1, 3), (3, 3), (4, 2), (4, 1), (3, 0), (1, 0), (0, 1)),),
    "T": (((0, 6), (4, 6)), ((2, 6), (2, 0))),
    "U": (((0, 6), (0, 1), (1, 0), (3, 0), (4, 1), (4, 6)),),
    "V": (((0, 6), (2, 0), (4, 6)),),
    "W": (((0, 6), (1, 0), (2, 4), (3, 0), (4, 6)),),
    "X": (((0, 6), (4, 0)), ((0, 0), (4, 6))),
    "Y": (((0, 6), (2, 3), (4, 6)), ((2, 3), (2, 0))),
    "Z": (((0, 6), (4, 6), (0, 0), (4, 0)),),
    "0": (_O, ((0, 1), (4, 5))),                       # slashed: never read as O
    "1": (((1, 5), (2, 6), (2, 0)), ((1, 0), (3, 0))),
    "2": (((0, 5), (1, 6), (3, 6), (4, 5), (4, 4), (0, 0), (4, 0)),),
    "3": (((0, 5), (1, 6), (3, 6), (4, 5), (4, 4), (3, 3), (4, 2), (4, 1), (3, 0), (1, 0), (0, 1)),
          ((1, 3), (3, 3))),
    "4": (((3, 0), (3, 6), (0, 2), (4, 2)),),
    "5": (((4, 6), (0, 6), (0, 3), (3, 3), (4, 2), (4, 1), (3, 0), (0, 0)),),
    "6": (_C[:-1] + ((4, 1), (4, 2), (3, 3), (0, 3)),),
    "7": (((0, 6), (4, 6), (1, 0)),),
    "8": (((1, 3), (0, 4), (0, 5), (1, 6), (3, 6), (4, 5), (4, 4), (3, 3), (1, 3), (0, 2), (0, 1), (1, 0),
           (3, 0), (4, 1), (4, 2), (3, 3)),),
    "9": (((0, 1), (1, 0), (3, 0), (4, 1), (4, 5), (3, 6), (1, 6), (0, 5), (0, 4), (1, 3), (4, 3)),),
}

#: The font: character -> its strokes, each (k, 2) float in cell units.
GLYPHS: dict[str, tuple[np.ndarray, ...]] = {
    ch: tuple(np.asarray(s, dtype=float) for s in strokes) for ch, strokes in _GLYPH_TABLE.items()}


def text_width(text: str, height: float) -> float:
    """Width of ``text`` drawn ``height`` mm high: first cell's left edge to the last one's right, mm."""
    if not text:
        return 0.0
    return ((len(text) - 1) * ADVANCE + CELL_W) * height / CELL_H


def _check_text(text: str, where: str) -> None:
    if not isinstance(text, str) or not text:
        raise ValueError(f"{where} = {text!r}: a label is a non-empty string of A-Z and 0-9")
    unknown = [ch for ch in text if ch not in GLYPHS]
    if unknown:
        raise ValueError(f"{where} = {text!r}: character {unknown[0]!r} has no glyph "
                         "(the stitch font draws A-Z and 0-9)")


def text_strokes(text: str, origin: np.ndarray, right: np.ndarray, height: float) -> list[np.ndarray]:
    """The strokes of ``text`` in the stitch font.

    Parameters
    ----------
    text : str
        characters of ``GLYPHS`` (A-Z, 0-9).
    origin : (2,) float
        the first cell's lower left corner (on the baseline), mm.
    right : (2,) float
        unit vector along the baseline; up is ``right`` turned a quarter counter-clockwise.
    height : float
        cap height, mm (> 0).

    Returns
    -------
    list of (k, 2) float
        one polyline per stroke, characters in order, mm.

    Raises
    ------
    ValueError
        naming a character that has no glyph.
    """
    _check_text(text, "text")
    r = np.asarray(right, dtype=float)
    basis = np.stack([r, [-r[1], r[0]]]) * (height / CELL_H)   # (2, 2): rows right, up, per unit
    o = np.asarray(origin, dtype=float)
    return [o + (s + [k * ADVANCE, 0.0]) @ basis for k, ch in enumerate(text) for s in GLYPHS[ch]]


def strokes_length(strokes: Sequence[np.ndarray]) -> float:
    """Total length of polylines (each (k, 2)), mm: what printing them extrudes along."""
    return float(sum(np.linalg.norm(np.diff(np.asarray(s, dtype=float), axis=0), axis=1).sum()
                     for s in strokes))


def _checked_marks(at: object, outward: object, labels: Sequence[str], tick_length: float,
                   text_height: float) -> tuple[np.ndarray, np.ndarray]:
    """``at`` and ``outward`` as (p, 2) arrays, every argument checked; the first problem raises."""
    a = np.asarray(at, dtype=float)
    n = np.asarray(outward, dtype=float)
    if a.size == 0:
        a, n = a.reshape(0, 2), n.reshape(0, 2)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"at must have shape (p, 2), got {a.shape}")
    if n.shape != a.shape:
        raise ValueError(f"outward must have the shape of at, {a.shape}, got {n.shape}")
    for name, v in (("at", a), ("outward", n)):
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if bad.size:
            raise ValueError(f"{name}[{bad[0]}] = {v[bad[0]].tolist()} is not finite")
    off = np.abs(np.hypot(n[:, 0], n[:, 1]) - 1.0)
    bad = np.flatnonzero(off > UNIT_TOLERANCE)
    if bad.size:
        i = bad[0]
        raise ValueError(f"outward[{i}] = {n[i].tolist()} has length {float(np.hypot(*n[i])):.9g}: "
                         f"must be a unit vector (within {UNIT_TOLERANCE:g})")
    if isinstance(labels, str) or len(labels) != len(a):
        raise ValueError(f"labels must be a list of {len(a)} strings (one per mark), got {labels!r}")
    for i, text in enumerate(labels):
        _check_text(text, f"labels[{i}]")
    if not (np.isfinite(tick_length) and tick_length > 0):
        raise ValueError(f"tick_length = {tick_length!r}: must be a finite number > 0 (mm)")
    if not (np.isfinite(text_height) and 0 < text_height < tick_length):
        raise ValueError(f"text_height = {text_height!r}: must be > 0 and below tick_length = "
                         f"{tick_length!r}, so the label fits inside the allowance")
    return a, n


def stitch_mark_strokes(at: np.ndarray, outward: np.ndarray, labels: Sequence[str], tick_length: float,
                        text_height: float | None = None) -> list[list[np.ndarray]]:
    """The polylines that print each stitch mark: its tick, then its label's strokes.

    Parameters
    ----------
    at : (p, 2) float
        the marks' points on the seam line, mm, front-side print coordinates.
    outward : (p, 2) float
        unit normals of the seam line there, pointing out of the panel (into the allowance).
    labels : list of p str
        each mark's label, characters A-Z and 0-9 (``"A1"``, ``"B12"``).
    tick_length : float
        the seam allowance, mm: each tick runs from ``at`` to ``at + tick_length * outward``, the
        point of the cutting line.
    text_height : float, optional
        the labels' cap height, mm, below ``tick_length``; default ``TEXT_FRACTION * tick_length``.

    Returns
    -------
    list of p lists of (k, 2) float
        per mark: the tick (2, 2) first, then the label's strokes. The label's band along
        ``outward`` is centred in the allowance (from (L - h)/2 to (L + h)/2, L the tick's length, h
        the text's height); its up is ``-outward``, and it starts ``TEXT_GAP * h`` to the right
        of the tick as seen from outside (along ``(-outward_y, outward_x)``).

    Raises
    ------
    ValueError
        naming the problem: a wrong shape, a non-finite value, a normal that is not a unit vector,
        a label count unlike the marks', a character with no glyph (and its label), a length <= 0
        or a text height that does not fit the allowance.
    """
    h = TEXT_FRACTION * tick_length if text_height is None else text_height
    a, n = _checked_marks(at, outward, labels, tick_length, h)
    right = np.column_stack([-n[:, 1], n[:, 0]])            # seen from outside, up = -outward
    baseline = 0.5 * (tick_length + h)                      # the text's bottom, distance along outward
    origin = a + baseline * n + TEXT_GAP * h * right
    out = []
    for i, text in enumerate(labels):
        tick = np.stack([a[i], a[i] + tick_length * n[i]])
        out.append([tick, *text_strokes(text, origin[i], right[i], h)])
    return out


def seam_of(label: str) -> str:
    """The seam's letters of a label: its leading letters (``"B12"`` -> ``"B"``)."""
    letters = label.rstrip("0123456789")
    if not letters:
        raise ValueError(f"label {label!r} starts with no seam letter")
    return letters


def make_stitch_marks(at: np.ndarray, outward: np.ndarray, labels: Sequence[str], tick_length: float,
                      text_height: float | None = None) -> list[StitchMark]:
    """The ``design.json`` entries of the marks (``Design.stitch_marks``): ``stitch_mark_strokes``'s
    strokes with each mark's label, seam (``seam_of``), point and normal; arguments as there."""
    strokes = stitch_mark_strokes(at, outward, labels, tick_length, text_height)
    a, n = np.asarray(at, dtype=float).reshape(-1, 2), np.asarray(outward, dtype=float).reshape(-1, 2)
    return [StitchMark(label=text, seam=seam_of(text), at=(float(a[i, 0]), float(a[i, 1])),
                       outward=(float(n[i, 0]), float(n[i, 1])),
                       strokes=[[(float(x), float(y)) for x, y in s] for s in strokes[i]])
            for i, text in enumerate(labels)]
