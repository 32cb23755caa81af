"""PNG of what the simulated printer deposited: machine and fabric coordinates.

Uses matplotlib's object API with the Agg canvas (no pyplot state), so rendering
is safe from any thread.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from .config import FrameConfig
from .record import Segment

__all__ = ["render_png"]

NOMINAL_BEAD_MM = 0.45
FILAMENT_AREA_MM2 = np.pi * (1.75 / 2) ** 2
COLORS = {"front": "#d62728", "back": "#1f77b4"}


def _bead_widths(segs: Sequence[Segment]) -> np.ndarray:
    """Bead width per segment: nominal, scaled by filament per mm relative to the median."""
    e = np.array([s.e for s in segs])
    length = np.hypot([s.x1 - s.x0 for s in segs], [s.y1 - s.y0 for s in segs])
    per_mm = e / np.maximum(length, 1e-9)
    ref = float(np.median(per_mm)) if len(per_mm) else 1.0
    # Same volume over a flat bead: width goes with filament per mm.
    scale = np.clip(per_mm / max(ref, 1e-12), 0.25, 4.0)
    return NOMINAL_BEAD_MM * scale


def _panel(fig: Figure, ax, segs: Sequence[Segment], fabric: bool, frame: FrameConfig,
           widths_mm: np.ndarray) -> None:
    if fabric:
        pts = np.array([[[s.fx0, s.fy0], [s.fx1, s.fy1]] for s in segs]).reshape(-1, 2, 2)
    else:
        pts = np.array([[[s.x0, s.y0], [s.x1, s.y1]] for s in segs]).reshape(-1, 2, 2)
    n_front = sum(1 for s in segs if s.side == "front")
    n_back = len(segs) - n_front
    name = "Fabric" if fabric else "Machine"
    ax.set_title(f"{name} coordinates: {n_front} front (red), {n_back} back (blue) segments",
                 fontsize=10)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, color="#dddddd", linewidth=0.5)
    cx, cy = frame.center
    if len(pts):
        lo = pts.reshape(-1, 2).min(axis=0)
        hi = pts.reshape(-1, 2).max(axis=0)
    else:
        lo, hi = np.array([cx - 50, cy - 50]), np.array([cx + 50, cy + 50])
    span = max(float((hi - lo).max()), 10.0)
    mid = (lo + hi) / 2
    half = span / 2 * 1.08
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    # The flip axis through the frame centre, for orientation.
    if frame.flip_axis == "y":
        ax.axvline(cx, color="#888888", linestyle="--", linewidth=0.8)
    else:
        ax.axhline(cy, color="#888888", linestyle="--", linewidth=0.8)
    if not len(pts):
        ax.text(0.5, 0.5, "no deposits", transform=ax.transAxes, ha="center", va="center")
        return
    # Line widths are in points: convert the bead width in mm with the panel's scale.
    ax.apply_aspect()
    bbox = ax.get_window_extent()
    pts_per_px = 72.0 / fig.dpi
    x0, x1 = ax.get_xlim()
    pt_per_mm = bbox.width * pts_per_px / (x1 - x0)
    lw = np.maximum(widths_mm * pt_per_mm, 0.4)
    colors = [COLORS.get(s.side, "black") for s in segs]
    ax.add_collection(LineCollection(pts, colors=colors, linewidths=lw, capstyle="round",
                                     alpha=0.85))


def render_png(segments: Sequence[Segment], path: str, frame: FrameConfig | None = None) -> None:
    """Write a two-panel PNG: deposits in machine and in fabric coordinates."""
    frame = frame or FrameConfig()
    segs = list(segments)
    fig = Figure(figsize=(14, 7), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    widths = _bead_widths(segs) if segs else np.zeros(0)
    for ax, fabric in zip(axes, (False, True)):
        _panel(fig, ax, segs, fabric, frame, widths)
    total_e = sum(s.e for s in segs)
    fig.suptitle(f"ribbond sim deposits: {len(segs)} segments, {total_e:.1f} mm filament")
    fig.legend(handles=[Line2D([], [], color=COLORS["front"], lw=3, label="front up"),
                        Line2D([], [], color=COLORS["back"], lw=3, label="back up"),
                        Line2D([], [], color="#888888", ls="--", label=f"flip axis ({frame.flip_axis})")],
               loc="lower center", ncol=3)
    fig.savefig(path)
