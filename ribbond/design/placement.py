"""Placing the flat surface in the printer's frame: front-side print coordinates (design-format.md).

Only rigid motions (a rotation and a translation) are used, so the flat surface keeps its
orientation: +z stays the front of the fabric.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..gcode.profiles import FrameSpec


def _hull(uv: np.ndarray) -> np.ndarray:
    try:
        return uv[ConvexHull(uv).vertices]
    except (QhullError, ValueError):
        return uv


def fit_scale(uv: np.ndarray, frame: FrameSpec, margin: float) -> float:
    """The factor by which ``uv`` (n, 2) could be scaled and still fit the frame less ``margin``."""
    w, h = uv.max(axis=0) - uv.min(axis=0)
    room_w, room_h = frame.size[0] - 2 * margin, frame.size[1] - 2 * margin
    if room_w <= 0 or room_h <= 0:
        raise ValueError(f"a margin of {margin} mm leaves no room in a {frame.size} mm frame")
    return float(min(room_w / max(w, 1e-12), room_h / max(h, 1e-12)))


def place_in_frame(uv: np.ndarray, frame: FrameSpec, margin: float = 0.0,
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


def registration_marks(uv: np.ndarray, frame: FrameSpec, offset: float = 5.0) -> np.ndarray:
    """Three registration marks (3, 2) outside the layout ``uv`` (n, 2), inside the frame.

    They sit ``offset`` mm diagonally out from three corners of the layout's bounding box (lower
    left, lower right, upper left): an L that is not symmetric under the flip, so a frame put
    back the wrong way round cannot be mistaken for a small misalignment.

    Raises
    ------
    ValueError
        when a mark would fall outside the frame (the layout leaves less than ``offset`` mm).
    """
    lo, hi = uv.min(axis=0) - offset, uv.max(axis=0) + offset
    marks = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]]])
    x0, y0, x1, y1 = frame.bounds
    out = (marks[:, 0] < x0) | (marks[:, 0] > x1) | (marks[:, 1] < y0) | (marks[:, 1] > y1)
    if out.any():
        raise ValueError(f"registration mark at {marks[np.argmax(out)].round(1).tolist()} falls outside the "
                         f"frame {frame.bounds}: the layout leaves less than {offset} mm around it")
    return marks
