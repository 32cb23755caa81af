"""``panels.png``: the target in 3D coloured by panel, beside the flat panels with their seams labelled.

Matplotlib's object API on the Agg canvas (no pyplot), as ``preview.py`` and ``deploy/picture.py``.
The flat panels are drawn at one scale, side by side in panel order, each with its number, its seam
lines in the colour of the panel across and the seam's letter, so a person sees which edge meets which.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

__all__ = ["panel_colours", "render_panels_png"]

_PALETTE = np.array([[0.12, 0.47, 0.71], [1.00, 0.50, 0.05], [0.17, 0.63, 0.17], [0.84, 0.15, 0.16],
                     [0.58, 0.40, 0.74], [0.55, 0.34, 0.29], [0.89, 0.47, 0.76], [0.50, 0.50, 0.50],
                     [0.74, 0.74, 0.13], [0.09, 0.75, 0.81], [0.40, 0.60, 0.90], [0.90, 0.60, 0.40]])


def panel_colours(count: int) -> np.ndarray:
    """(count, 3) RGB of each panel (the dashboard uses the same order)."""
    return _PALETTE[np.arange(count) % len(_PALETTE)]


def _target_view(fig: Figure, V: np.ndarray, F: np.ndarray, labels: np.ndarray, rect: list[float]) -> None:
    ax = fig.add_axes(rect, projection="3d")
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    light = np.array([0.3, -0.5, 0.81])
    shade = 0.45 + 0.55 * np.abs(n @ light)
    colours = np.clip(panel_colours(labels.max() + 1)[labels] * shade[:, None], 0, 1)
    ax.add_collection3d(Poly3DCollection(V[F], facecolors=colours, edgecolors="none"))
    lo, hi = V.min(axis=0), V.max(axis=0)
    c, r = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=30, azim=-60)
    ax.set_title("target, coloured by panel", fontsize=11)
    ax.tick_params(labelsize=7)
    for k in range(labels.max() + 1):
        centre = V[F[labels == k]].mean(axis=(0, 1))
        ax.text(*centre, str(k + 1), fontsize=12, weight="bold", color="white",
                bbox=dict(boxstyle="circle,pad=0.2", fc=tuple(panel_colours(k + 1)[k]), ec="none"))


def render_panels_png(V: np.ndarray, F: np.ndarray, labels: np.ndarray, outlines: Sequence[np.ndarray],
                      seams: Sequence[tuple[str, int, int, np.ndarray, np.ndarray]], *, title: str = "",
                      dpi: int = 100) -> bytes:
    """The PNG bytes of ``panels.png``.

    Parameters
    ----------
    V : (n, 3) target vertices, mm; F : (m, 3) faces; labels : (m,) panel (0-based) of each face.
    outlines : per panel, (q, 2) its flat outline in its print coordinates, mm.
    seams : per seam (label, panel a, panel b, flat line on a (p, 2), flat line on b (p, 2)).
    """
    k = len(outlines)
    columns = min(k, 4)                                    # the flat panels in rows of at most four
    rows = -(-k // columns)
    fig = Figure(figsize=(6 + 3.2 * columns, max(6.2, 3.4 * rows)), dpi=dpi)
    FigureCanvasAgg(fig)
    share = 6.0 / (6 + 3.2 * columns)
    _target_view(fig, V, F, labels, [0.0, 0.05, share, 0.85])
    ax = fig.add_axes([share + 0.02, 0.06, 0.97 - share, 0.84])
    colours = panel_colours(k)
    cell = max(float((o.max(axis=0) - o.min(axis=0)).max()) for o in outlines) + 25.0
    offsets = []
    for j, outline in enumerate(outlines):
        lo = outline.min(axis=0)
        offsets.append(np.array([(j % columns) * cell, -(j // columns) * cell]) - lo)
        P = outline + offsets[-1]
        ax.fill(P[:, 0], P[:, 1], color=tuple(colours[j]), alpha=0.25, lw=0)
        ax.plot(*np.vstack([P, P[:1]]).T, color=tuple(colours[j]), lw=1.2)
        ax.text(*(0.5 * (P.min(axis=0) + P.max(axis=0))), f"panel {j + 1}", ha="center", va="center",
                fontsize=12, weight="bold", color=tuple(colours[j] * 0.6))
    for label, a, b, line_a, line_b in seams:
        for me, other, line in ((a, b, line_a), (b, a, line_b)):
            P = line + offsets[me]
            ax.plot(P[:, 0], P[:, 1], color=tuple(colours[other]), lw=3.0, solid_capstyle="butt")
            mid = P[len(P) // 2]
            ax.text(mid[0], mid[1], f"{label}→{other + 1}", fontsize=9, weight="bold", ha="center",
                    va="center", bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=tuple(colours[other])))
    ax.set_aspect("equal")
    ax.set_title("flat panels (print coordinates, mm); a seam is drawn in the colour of the panel it meets",
                 fontsize=10)
    ax.tick_params(labelsize=7)
    if title:
        fig.suptitle(title, fontsize=12)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
