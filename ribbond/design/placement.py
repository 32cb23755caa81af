"""Placing the flat surface in the printer's frame: front-side print coordinates (design-format.md).

Only rigid motions (a rotation and a translation) are used, so the flat surface keeps its
orientation: +z stays the front of the fabric.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy.spatial import ConvexHull, QhullError


class Frame(Protocol):
    """The printable rectangle, as placing a layout needs it (a printer profile's ``FrameSpec``,
    ``ribbond.gcode.profiles``, is one: the design engine reads no profile, so it names only this)."""

    @property
    def center(self) -> tuple[float, float]: ...

    @property
    def size(self) -> tuple[float, float]: ...

    @property
    def bounds(self) -> tuple[float, float, float, float]: ...


def _hull(uv: np.ndarray) -> np.ndarray:
    try:
        return uv[ConvexHull(uv).vertices]
    except (QhullError, ValueError):
        return uv


def fit_scale(uv: np.ndarray, frame: Frame, margin: float) -> float:
    """The factor by which ``uv`` (n, 2) could be scaled and still fit the frame less ``margin``."""
    w, h = uv.max(axis=0) - uv.min(axis=0)
    room_w, room_h = frame.size[0] - 2 * margin, frame.size[1] - 2 * margin
    if room_w <= 0 or room_h <= 0:
        raise ValueError(f"a margin of {margin} mm leaves no room in a {frame.size} mm frame")
    return float(min(room_w / max(w, 1e-12), room_h / max(h, 1e-12)))


def place_in_frame(uv: np.ndarray, frame: Frame, margin: float = 0.0,
                   samples: int = 720) -> tuple[np.ndarray, float]:
    """Turn the layout so that it fits the frame best, and centre it there.

    Parameters
    ----------
    uv : (n, 2) flat positions.
    frame : the printable rectangle.
    samples : rotations tried over half a turn, besides the directions of the hull's edges.

    Returns
    -------
    placed : (n, 2) in print coordinates; angle : the rotation applied (radians, CCW).
    """
    hull = _hull(uv)
    edges = np.roll(hull, -1, axis=0) - hull
    angles = np.concatenate([np.linspace(0.0, np.pi, samples, endpoint=False),
                             np.mod(-np.arctan2(edges[:, 1], edges[:, 0]), np.pi)])
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x = c * hull[None, :, 0] - s * hull[None, :, 1]            # (angles, hull points)
    y = s * hull[None, :, 0] + c * hull[None, :, 1]
    w, h = x.max(axis=1) - x.min(axis=1), y.max(axis=1) - y.min(axis=1)
    room_w, room_h = frame.size[0] - 2 * margin, frame.size[1] - 2 * margin
    scale = np.minimum(room_w / np.maximum(w, 1e-12), room_h / np.maximum(h, 1e-12))
    best = int(np.argmax(scale))
    angle = float(angles[best])
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    placed = uv @ R.T
    centre = 0.5 * (placed.max(axis=0) + placed.min(axis=0))
    return placed - centre + np.asarray(frame.center), angle


def registration_marks(uv: np.ndarray, frame: Frame, offset: float = 5.0) -> np.ndarray:
    """Three registration marks (3, 2) just outside the layout ``uv`` (n, 2), inside the frame.

    Candidates are the layout's convex-hull corners pushed ``offset`` mm outward (so a mark is at
    least that far from the outline, and close to the ribbons: the print head passes by anyway);
    the three spanning the largest triangle are kept, so a small rotation of the flipped frame
    moves them as much as anything in the layout. A triangle of three distinct marks is not
    symmetric under the flip, so a frame put back the wrong way round is not mistaken for a small
    misalignment.

    Raises
    ------
    ValueError
        when fewer than three marks fit in the frame.
    """
    hull = _hull(uv)
    if len(hull) < 3:
        raise ValueError("the layout is degenerate (no area): no place for registration marks")
    prev, nxt = np.roll(hull, 1, axis=0), np.roll(hull, -1, axis=0)

    def outward(edge: np.ndarray) -> np.ndarray:
        n = np.column_stack([edge[:, 1], -edge[:, 0]])          # right of a CCW edge: outside
        return n / np.maximum(np.linalg.norm(n, axis=1), 1e-12)[:, None]
    bis = outward(hull - prev) + outward(nxt - hull)
    bis /= np.maximum(np.linalg.norm(bis, axis=1), 1e-12)[:, None]
    cand = hull + offset * bis
    x0, y0, x1, y1 = frame.bounds
    fits = (cand[:, 0] >= x0) & (cand[:, 0] <= x1) & (cand[:, 1] >= y0) & (cand[:, 1] <= y1)
    cand = cand[fits]
    if len(cand) < 3:
        raise ValueError(f"fewer than three registration marks fit in the frame {frame.bounds} at "
                         f"{offset} mm outside the layout")
    if len(cand) > 48:                                           # keep the search small
        cand = cand[np.linspace(0, len(cand) - 1, 48).round().astype(int)]
    idx = np.array(np.meshgrid(*(np.arange(len(cand)),) * 3, indexing="ij")).reshape(3, -1).T
    idx = idx[(idx[:, 0] < idx[:, 1]) & (idx[:, 1] < idx[:, 2])]
    a, b, c = cand[idx[:, 0]], cand[idx[:, 1]], cand[idx[:, 2]]
    area = np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    return cand[idx[int(np.argmax(area))]]
