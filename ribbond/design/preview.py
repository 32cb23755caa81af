"""The layout preview of a design: ``preview.svg`` and ``preview.png`` (design-format.md).

The flat (pre-stretched) surface in front-side print coordinates, as in Fig. 2 (c–d) of the paper:
the stretch σ2 across the ribbons as a colour map underneath, the outline of the flat surface,
front ribbons in red and back ribbons in blue at their real width, the registration marks numbered
from 1 (as the daemon's alignment step counts them), a panel's stitch marks (their ticks and labels as
thin dark lines, SVG id ``stitch-marks``; issue 26), the printable frame and the flip axis the frame
is turned over about for the back side.

``render_preview`` is a pure function: it returns the bytes of both files and writes nothing (the
caller writes them atomically with the rest of the design folder). It uses matplotlib's object API
on the Agg canvas, never pyplot, so it keeps no global figure state and can run in any thread.

Ribbons are drawn as filled outlines (the centre line buffered by half the ribbon width, flat ends),
so their width is in data units and stays right at any figure size and resolution. All ribbons of a
side form one compound path: the SVG holds one ``<path>`` per side (ids ``front-ribbons`` and
``back-ribbons``). The colour map is rasterized in the SVG, so a 100k-face design does not become
100k polygons; the outline, ribbons, marks and frame stay vector.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import matplotlib
import numpy as np
import shapely
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, PathPatch, Rectangle
from matplotlib.path import Path as MplPath

__all__ = ["RibbonLike", "StitchMarkLike", "render_preview", "boundary_edges", "SIDE_COLORS"]

#: Ribbon colours per side (as in the paper's figures: front red, back blue).
SIDE_COLORS = {"front": "#d62728", "back": "#1f4fd6"}
#: The outline of the flat surface.
OUTLINE_COLOR = "#1a1a1a"
#: The printable frame.
FRAME_COLOR = "#808080"
#: A panel's stitch marks, and their line width in points.
STITCH_COLOR, STITCH_LINEWIDTH = "#262626", 0.6
#: Salt of the SVG's element ids, so that the same design gives the same file.
SVG_HASHSALT = "ribbond-preview"
#: How far the colour map is mixed towards white, so the ribbons stand out on it.
COLORMAP_LIGHTEN = 0.5
#: How the registration marks are drawn (a circle and a cross each), and shown in the legend.
_MARK_STYLE = dict(linestyle="none", color="black", markersize=9, markeredgewidth=1.0)
#: Size of the axes' longer side, inches (the figure adds the colour bar, title and legend).
AXES_INCHES = 8.0

# rc_context changes matplotlib's global rcParams: one SVG save at a time within the process, so
# that no render restores the salt while another one is still writing its file.
_SVG_LOCK = threading.Lock()


@runtime_checkable
class RibbonLike(Protocol):
    """What the preview needs of a ribbon (``ribbond.design.format.Ribbon`` is one)."""

    side: str
    points: Sequence[tuple[float, float]]


@runtime_checkable
class StitchMarkLike(Protocol):
    """What the preview needs of a stitch mark (``ribbond.design.format.StitchMark`` is one)."""

    strokes: Sequence[Sequence[tuple[float, float]]]


def _light_colormap(name: str = "viridis", lighten: float = COLORMAP_LIGHTEN) -> ListedColormap:
    """``name`` mixed towards white by ``lighten``: a sequential map that stays under the ribbons."""
    base = matplotlib.colormaps[name](np.linspace(0.0, 1.0, 256))
    rgb = (1.0 - lighten) * base[:, :3] + lighten
    return ListedColormap(rgb, name=f"{name}_light")


def boundary_edges(F: np.ndarray) -> np.ndarray:
    """The edges of ``F`` used by exactly one face.

    Parameters
    ----------
    F : (m, 3) int
        faces.

    Returns
    -------
    (b, 2) int
        vertex index pairs of the boundary edges (any number of loops), each in the direction of
        the face that holds it.
    """
    directed = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(directed, axis=1)
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    return directed[np.sort(first[counts == 1])]


# ---------------------------------------------------------------------------------------------
# Validation


def _float_array(value: object, name: str, shape_text: str, columns: int | None) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array of shape {shape_text}: {exc}") from None
    if columns is not None and a.size == 0:
        a = a.reshape(0, columns)     # an empty list is an empty set of rows
    if columns is None:
        ok = a.ndim == 1
    else:
        ok = a.ndim == 2 and a.shape[1] == columns
    if not ok:
        raise ValueError(f"{name} must have shape {shape_text}, got {a.shape}")
    finite = np.isfinite(a) if a.ndim == 1 else np.isfinite(a).all(axis=1)
    bad = np.flatnonzero(~finite)
    if bad.size:
        raise ValueError(f"{name}[{bad[0]}] = {a[bad[0]].tolist()} is not finite "
                         f"({bad.size} such row(s))")
    return a


def _faces(F: object, n: int) -> np.ndarray:
    a = np.asarray(F)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"F must have shape (m, 3), got {a.shape}")
    if len(a) == 0:
        raise ValueError("F is empty: the flat surface needs at least one face")
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"F must hold integer vertex indices, got dtype {a.dtype}")
    bad = np.flatnonzero(((a < 0) | (a >= n)).any(axis=1))
    if bad.size:
        raise ValueError(f"F[{bad[0]}] = {a[bad[0]].tolist()} refers to a vertex outside "
                         f"0..{n - 1} (flat_uv has {n} vertices)")
    return a.astype(np.int64, copy=False)


def _bounds_pair(value: object, name: str) -> tuple[float, float]:
    a = np.asarray(value, dtype=float).ravel()
    if a.shape != (2,) or not np.isfinite(a).all() or a[0] > a[1]:
        raise ValueError(f"{name} = {value!r}: need two finite numbers (low, high) with low <= high")
    return float(a[0]), float(a[1])


def _frame(value: object) -> tuple[float, float, float, float]:
    a = np.asarray(value, dtype=float).ravel()
    if a.shape != (4,) or not np.isfinite(a).all() or a[0] >= a[2] or a[1] >= a[3]:
        raise ValueError(f"frame_bounds = {value!r}: need four finite numbers "
                         "(x_min, y_min, x_max, y_max) with x_min < x_max and y_min < y_max")
    return float(a[0]), float(a[1]), float(a[2]), float(a[3])


def _ribbon_points(ribbons: Sequence[RibbonLike]) -> tuple[list[np.ndarray], list[str]]:
    points, sides = [], []
    for i, r in enumerate(ribbons):
        side = getattr(r, "side", None)
        if side not in SIDE_COLORS:
            raise ValueError(f"ribbons[{i}] has side {side!r}: must be 'front' or 'back'")
        try:
            p = np.asarray(getattr(r, "points", None), dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"ribbons[{i}].points must be (x, y) pairs: {exc}") from None
        if p.ndim != 2 or p.shape[1] != 2:
            raise ValueError(f"ribbons[{i}].points must have shape (k, 2), got {p.shape}")
        if len(p) < 2:
            raise ValueError(f"ribbons[{i}] has {len(p)} point(s): a ribbon needs at least 2")
        if not np.isfinite(p).all():
            raise ValueError(f"ribbons[{i}].points holds a non-finite coordinate")
        points.append(p)
        sides.append(side)
    return points, sides


def _stitch_strokes(stitch_marks: Sequence[object] | None) -> list[np.ndarray]:
    """Every stroke of the stitch marks, each (k, 2): a mark is a ``StitchMarkLike`` or a sequence of
    polylines (``stitch.stitch_mark_strokes``' items)."""
    out = []
    for i, mark in enumerate(stitch_marks or []):
        strokes = mark.strokes if isinstance(mark, StitchMarkLike) else mark
        for k, stroke in enumerate(strokes):                       # type: ignore[arg-type]
            p = _float_array(stroke, f"stitch_marks[{i}] stroke {k}", "(k, 2)", 2)
            if len(p) < 2:
                raise ValueError(f"stitch_marks[{i}] stroke {k} has {len(p)} point(s): a stroke needs at least 2")
            out.append(p)
    return out


# ---------------------------------------------------------------------------------------------
# Drawing


def _ribbon_path(points: list[np.ndarray], width: float) -> MplPath | None:
    """One compound path: every polyline of ``points`` buffered by ``width / 2`` (flat ends).

    Exteriors run counter-clockwise and holes clockwise, so the non-zero fill rule of Agg and SVG
    fills the ribbons, their overlaps included, and leaves the holes of self-crossing ones empty.
    """
    if not points:
        return None
    coords = np.concatenate(points)
    index = np.repeat(np.arange(len(points)), [len(p) for p in points])
    lines = shapely.linestrings(coords, indices=index)
    shapes = shapely.buffer(lines, 0.5 * width, cap_style="flat", join_style="mitre",
                            mitre_limit=2.0)
    polygons = shapely.get_parts(shapes)
    polygons = polygons[~shapely.is_empty(polygons)]
    if len(polygons) == 0:
        return None
    if hasattr(shapely, "orient_polygons"):       # shapely >= 2.1
        polygons = shapely.orient_polygons(polygons, exterior_cw=False)
    else:
        from shapely.geometry.polygon import orient
        polygons = np.array([orient(p, 1.0) for p in polygons], dtype=object)
    rings = shapely.get_rings(polygons)
    xy, ring = shapely.get_coordinates(rings, return_index=True)
    codes = np.full(len(xy), MplPath.LINETO, dtype=MplPath.code_type)
    starts = np.flatnonzero(np.r_[True, ring[1:] != ring[:-1]])
    codes[starts] = MplPath.MOVETO
    codes[np.r_[starts[1:], len(xy)] - 1] = MplPath.CLOSEPOLY
    return MplPath(xy, codes)


def _extent(uv: np.ndarray, points: list[np.ndarray], width: float, marks: np.ndarray | None,
            frame: tuple[float, float, float, float] | None,
            stitches: list[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corner of everything drawn, with a margin."""
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    if stitches:
        allp = np.concatenate(stitches)
        lo, hi = np.minimum(lo, allp.min(axis=0)), np.maximum(hi, allp.max(axis=0))
    if points:
        allp = np.concatenate(points)
        lo = np.minimum(lo, allp.min(axis=0) - 0.5 * width)
        hi = np.maximum(hi, allp.max(axis=0) + 0.5 * width)
    if marks is not None and len(marks):
        lo, hi = np.minimum(lo, marks.min(axis=0)), np.maximum(hi, marks.max(axis=0))
    if frame is not None:
        lo = np.minimum(lo, [frame[0], frame[1]])
        hi = np.maximum(hi, [frame[2], frame[3]])
    span = hi - lo
    pad = 0.04 * max(float(span.max()), 1e-6)
    span = np.maximum(span, 1e-3 * max(float(span.max()), 1e-6))  # a degenerate layout keeps a size
    mid = 0.5 * (lo + hi)
    return mid - 0.5 * span - pad, mid + 0.5 * span + pad


def _figure_size(lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Figure size (inches) whose axes box fits the layout's aspect, plus room for the rest."""
    w, h = hi - lo
    ratio = float(np.clip(h / w, 0.3, 3.0))
    ax_w, ax_h = (AXES_INCHES, AXES_INCHES * ratio) if ratio <= 1.0 else (AXES_INCHES / ratio,
                                                                         AXES_INCHES)
    return ax_w + 2.0, ax_h + 1.6


@dataclass(frozen=True)
class _Checked:
    """The preview's inputs, checked: arrays of the right shapes and the colour range of σ2."""

    uv: np.ndarray
    faces: np.ndarray
    s2: np.ndarray
    width: float
    points: list[np.ndarray]
    sides: list[str]
    marks: np.ndarray | None
    frame: tuple[float, float, float, float] | None
    vmin: float
    vmax: float
    stitches: list[np.ndarray]


def _checked(flat_uv: np.ndarray, F: np.ndarray, sigma2: np.ndarray, ribbons: Sequence[RibbonLike],
             ribbon_width: float, marks: np.ndarray | None, frame_bounds: tuple[float, float, float, float] | None,
             sigma2_bounds: tuple[float, float] | None, dpi: int, flip_axis: str | None,
             stitch_marks: Sequence[object] | None = None) -> _Checked:
    """Check ``render_preview``'s arguments in its documented order; the first problem raises."""
    uv = _float_array(flat_uv, "flat_uv", "(n, 2)", 2)
    if len(uv) < 3:
        raise ValueError(f"flat_uv has {len(uv)} vertices: a surface needs at least 3")
    faces = _faces(F, len(uv))
    s2 = _float_array(sigma2, "sigma2", "(m,)", None)
    if len(s2) != len(faces):
        raise ValueError(f"sigma2 has {len(s2)} values but F has {len(faces)} faces: one per face")
    width = float(ribbon_width)
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"ribbon_width = {ribbon_width!r}: must be a finite number > 0 (mm)")
    points, sides = _ribbon_points(ribbons)
    mk = None
    if marks is not None:
        mk = _float_array(marks, "marks", "(k, 2)", 2)
    frame = _frame(frame_bounds) if frame_bounds is not None else None
    if flip_axis not in ("x", "y", None):
        raise ValueError(f"flip_axis = {flip_axis!r}: must be 'x', 'y' or None")
    if sigma2_bounds is not None:
        vmin, vmax = _bounds_pair(sigma2_bounds, "sigma2_bounds")
    else:
        vmin, vmax = float(s2.min()), float(s2.max())
    if vmax - vmin < 1e-9 * max(1.0, abs(vmin)):
        vmin, vmax = vmin - 0.005 * max(1.0, abs(vmin)), vmax + 0.005 * max(1.0, abs(vmax))
    if not (isinstance(dpi, (int, np.integer)) and 10 <= dpi <= 1200):
        raise ValueError(f"dpi = {dpi!r}: must be an integer in 10..1200")
    return _Checked(uv=uv, faces=faces, s2=s2, width=width, points=points, sides=sides, marks=mk, frame=frame,
                    vmin=vmin, vmax=vmax, stitches=_stitch_strokes(stitch_marks))


def render_preview(flat_uv: np.ndarray,
                   F: np.ndarray,
                   sigma2: np.ndarray,
                   ribbons: Sequence[RibbonLike],
                   ribbon_width: float,
                   marks: np.ndarray | None = None,
                   frame_bounds: tuple[float, float, float, float] | None = None,
                   title: str = "",
                   sigma2_bounds: tuple[float, float] | None = None,
                   dpi: int = 150,
                   flip_axis: str | None = "y",
                   stitch_marks: Sequence[StitchMarkLike | Sequence[np.ndarray]] | None = None
                   ) -> tuple[bytes, bytes]:
    """Render the layout preview of a design: ``(preview.svg, preview.png)`` as bytes.

    Parameters
    ----------
    flat_uv : (n, 2) float
        the flat (pre-stretched) surface in front-side print coordinates, mm.
    F : (m, 3) int
        faces (counter-clockwise); indices into ``flat_uv``.
    sigma2 : (m,) float
        per-face stretch across the ribbons, drawn as the colour map.
    ribbons : sequence of RibbonLike
        each with ``side`` (``"front"`` or ``"back"``) and ``points``, a polyline of at least two
        (x, y) points in mm (front-side print coordinates).
    ribbon_width : float
        ribbon width, mm (> 0): ribbons are drawn at this width in data units.
    marks : (k, 2) float, optional
        registration marks, mm; labelled 1..k in their order (SVG ids ``registration-mark-i``).
    frame_bounds : (x_min, y_min, x_max, y_max), optional
        the printable frame, drawn as a dashed rectangle.
    title : str
        the title line.
    sigma2_bounds : (low, high), optional
        the colour range of σ2; default: the range of ``sigma2``. Values outside are drawn in the
        end colours and the colour bar shows arrows.
    dpi : int
        resolution of the PNG and of the rasterized colour map in the SVG.
    flip_axis : "x", "y" or None
        the frame's axis the fabric is turned over about for the back side (the printer profile's
        ``frame.flip_axis``; the shipped profiles use "y"), drawn through the frame's centre when
        ``frame_bounds`` is given (SVG id ``flip-axis``); None draws none.
    stitch_marks : sequence, optional
        a panel's stitch marks (issue 26), thin dark lines (SVG id ``stitch-marks``): each a
        ``StitchMarkLike`` or a sequence of (k, 2) polylines (``stitch.stitch_mark_strokes``), mm.

    Returns
    -------
    (svg, png) : tuple of bytes
        the SVG document (deterministic: same input, same bytes) and the PNG image.

    Raises
    ------
    ValueError
        naming the problem: a wrong shape, a non-finite value, a face index out of range, a ribbon
        (by index) with an unknown side or fewer than two points, invalid bounds, a stitch mark's
        stroke (by mark and stroke) of a wrong shape or fewer than two points.
    """
    c = _checked(flat_uv, F, sigma2, ribbons, ribbon_width, marks, frame_bounds, sigma2_bounds, dpi, flip_axis,
                 stitch_marks)
    lo, hi = _extent(c.uv, c.points, c.width, c.marks, c.frame, c.stitches)
    fig = Figure(figsize=_figure_size(lo, hi), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = _axes(fig, lo, hi)
    _draw_stretch(fig, ax, c)
    if c.frame is not None:
        _draw_frame(ax, c.frame, flip_axis)
    counts = _draw_ribbons(ax, c.points, c.sides, c.width)
    outline = LineCollection(c.uv[boundary_edges(c.faces)], colors=OUTLINE_COLOR, linewidths=1.1,
                             capstyle="round", joinstyle="round", zorder=3)
    outline.set_gid("outline")
    ax.add_collection(outline, autolim=False)
    if c.marks is not None and len(c.marks):
        _draw_marks(ax, c.marks)
    _draw_stitches(ax, c.stitches)
    _legend(fig, counts, c.marks, c.frame, flip_axis, len(stitch_marks or []))
    if title:
        fig.suptitle(title, fontsize=11, parse_math=False)  # a file name may hold "$"
    return _saved(fig, dpi)


def _axes(fig: Figure, lo: np.ndarray, hi: np.ndarray) -> Axes:
    """The axes over the layout's extent, equal scale, in millimetres, with a light grid."""
    ax = fig.add_subplot()
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (mm, front-side print coordinates)")
    ax.set_ylabel("y (mm)")
    ax.tick_params(labelsize=8)
    ax.set_axisbelow(True)
    ax.grid(True, color="#e6e6e6", linewidth=0.5)
    return ax


def _draw_stretch(fig: Figure, ax: Axes, c: _Checked) -> None:
    """σ2 underneath: one flat-coloured triangle per face, rasterized in the SVG; and its colour bar."""
    norm = Normalize(vmin=c.vmin, vmax=c.vmax)
    field = PolyCollection(c.uv[c.faces], array=c.s2, cmap=_light_colormap(), norm=norm, edgecolors="none",
                           linewidths=0.0, antialiased=False, rasterized=True, zorder=1)
    ax.add_collection(field, autolim=False)
    below, above = bool((c.s2 < c.vmin).any()), bool((c.s2 > c.vmax).any())
    extend = {(False, False): "neither", (True, False): "min", (False, True): "max",
              (True, True): "both"}[(below, above)]
    cbar = fig.colorbar(field, ax=ax, extend=extend, shrink=0.85, pad=0.02, aspect=30)
    cbar.set_label(r"$\sigma_2$ (stretch across the ribbons)")
    cbar.ax.tick_params(labelsize=8)


def _draw_frame(ax: Axes, frame: tuple[float, float, float, float], flip_axis: str | None) -> None:
    """The printable frame, dashed, and the axis the fabric is turned over about, through its centre."""
    rect = Rectangle((frame[0], frame[1]), frame[2] - frame[0], frame[3] - frame[1], fill=False,
                     edgecolor=FRAME_COLOR, linestyle="--", linewidth=1.0, zorder=0.5)
    rect.set_gid("frame")
    ax.add_patch(rect)
    if flip_axis is not None:
        cx, cy = (frame[0] + frame[2]) / 2, (frame[1] + frame[3]) / 2
        xs, ys = ([cx, cx], [frame[1], frame[3]]) if flip_axis == "y" else ([frame[0], frame[2]], [cy, cy])
        axis_line = Line2D(xs, ys, color=FRAME_COLOR, linestyle="-.", linewidth=1.0, zorder=0.6)
        axis_line.set_gid("flip-axis")
        ax.add_line(axis_line)


def _draw_ribbons(ax: Axes, points: list[np.ndarray], sides: list[str], width: float) -> dict[str, int]:
    """Ribbons at their real width: one compound path per side, in data units. Returns the count per side."""
    counts = {"front": 0, "back": 0}
    for side in ("back", "front"):
        mine = [p for p, s in zip(points, sides) if s == side]
        counts[side] = len(mine)
        path = _ribbon_path(mine, width)
        if path is not None:
            patch = PathPatch(path, facecolor=SIDE_COLORS[side], edgecolor="none", linewidth=0.0,
                              zorder=2)
            patch.set_gid(f"{side}-ribbons")
            ax.add_patch(patch)
    return counts


def _draw_marks(ax: Axes, mk: np.ndarray) -> None:
    """The registration marks, a circle and a cross each, numbered from 1."""
    for marker, part in (("o", "circles"), ("+", "crosses")):
        m = Line2D(mk[:, 0], mk[:, 1], marker=marker, markerfacecolor="none", zorder=4, **_MARK_STYLE)
        m.set_gid(f"registration-marks-{part}")
        ax.add_line(m)
    for number, (x, y) in enumerate(mk, start=1):
        label = ax.annotate(str(number), (x, y), xytext=(5, 5), textcoords="offset points",
                            fontsize=9, fontweight="bold", color="black", zorder=5)
        label.set_gid(f"registration-mark-{number}")


def _draw_stitches(ax: Axes, strokes: list[np.ndarray]) -> None:
    """A panel's stitch marks: every stroke a thin dark line, one collection (SVG id ``stitch-marks``)."""
    if not strokes:
        return
    lines = LineCollection(strokes, colors=STITCH_COLOR, linewidths=STITCH_LINEWIDTH, capstyle="round",
                           joinstyle="round", zorder=4)
    lines.set_gid("stitch-marks")
    ax.add_collection(lines, autolim=False)


def _legend(fig: Figure, counts: dict[str, int], mk: np.ndarray | None,
            frame: tuple[float, float, float, float] | None, flip_axis: str | None, stitches: int = 0) -> None:
    """The legend under the axes: the ribbons per side, the outline, the marks, the frame and flip axis."""
    handles: list[object] = [
        Patch(facecolor=SIDE_COLORS["front"], label=f"front ribbons ({counts['front']})"),
        Patch(facecolor=SIDE_COLORS["back"], label=f"back ribbons ({counts['back']})"),
        Line2D([], [], color=OUTLINE_COLOR, linewidth=1.1,
               label="outline (seam line: cut at the ticks' ends)" if stitches else "outline (cut line)"),
    ]
    labels = [h.get_label() for h in handles]  # type: ignore[attr-defined]
    if mk is not None:
        circle = Line2D([], [], marker="o", markerfacecolor="none", **_MARK_STYLE)
        cross = Line2D([], [], marker="+", **_MARK_STYLE)
        handles.append((circle, cross))
        labels.append(f"registration marks 1–{len(mk)}" if len(mk) else "registration marks (0)")
    if stitches:
        handles.append(Line2D([], [], color=STITCH_COLOR, linewidth=STITCH_LINEWIDTH))
        labels.append(f"stitch marks ({stitches})")
    if frame is not None:
        handles.append(Line2D([], [], color=FRAME_COLOR, linestyle="--", linewidth=1.0))
        labels.append("printable frame")
        if flip_axis is not None:
            handles.append(Line2D([], [], color=FRAME_COLOR, linestyle="-.", linewidth=1.0))
            labels.append(f"flip axis ({flip_axis})")
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(handles), 5),
               frameon=False, fontsize=9, handlelength=2.2)


def _saved(fig: Figure, dpi: int) -> tuple[bytes, bytes]:
    """The figure as SVG (deterministic ids, no date) and PNG bytes."""
    svg = io.BytesIO()
    with _SVG_LOCK, matplotlib.rc_context({"svg.hashsalt": SVG_HASHSALT}):
        fig.savefig(svg, format="svg", dpi=dpi, metadata={"Date": None})
    png = io.BytesIO()
    fig.savefig(png, format="png", dpi=dpi)
    return svg.getvalue(), png.getvalue()
