"""``deployed.png``: the target and the predicted surface side by side in 3D, the deviation as a colour
map (as the paper's Fig. 9), with a colour bar in % of the target's bounding-box diagonal.

Matplotlib's object API on the Agg canvas (no pyplot, no global figure state), as ``preview.py``.
Both views share one camera and one scale, in the target's principal frame (seen from above its
smallest extent); the prediction is drawn registered onto the target.
"""

from __future__ import annotations

import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

import matplotlib

__all__ = ["render_deployed_png"]

#: The camera (degrees), the same for both views.
ELEVATION, AZIMUTH = 28.0, -60.0


def _view(ax, V: np.ndarray, F: np.ndarray, colors: np.ndarray, lo: np.ndarray, hi: np.ndarray, title: str) -> None:
    poly = Poly3DCollection(V[F], facecolors=colors, edgecolors="none", linewidths=0.0)
    ax.add_collection3d(poly)
    c, r = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=ELEVATION, azim=AZIMUTH)
    ax.set_title(title, fontsize=11)
    ax.set_xlabel("x (mm)", fontsize=8)
    ax.set_ylabel("y (mm)", fontsize=8)
    ax.set_zlabel("z (mm)", fontsize=8)
    ax.tick_params(labelsize=7)


def _shade(V: np.ndarray, F: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """Face colours (t, 4) lit by a light from the camera side (both sides of the sheet lit alike)."""
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    el, az = np.radians(ELEVATION + 20), np.radians(AZIMUTH - 30)
    light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    k = 0.45 + 0.55 * np.abs(n @ light)
    out = np.ones((len(F), 4))
    out[:, :3] = np.clip(rgb[:, :3] * k[:, None], 0, 1)
    return out


def render_deployed_png(target_V: np.ndarray, target_F: np.ndarray, V: np.ndarray, F: np.ndarray,
                        distance: np.ndarray, diagonal: float | None = None, *, title: str = "",
                        dpi: int = 110) -> bytes:
    """The PNG bytes of the target (grey) beside the prediction coloured by its deviation.

    Parameters
    ----------
    target_V : (n, 3), target_F : (m, 3) the target surface, mm.
    V : (k, 3) the predicted surface registered onto the target; F : (t, 3) its faces.
    distance : (k,) each predicted vertex's distance to the target, mm.
    diagonal : the target's bounding-box diagonal, mm (default: computed from target_V).
    title : a line above both views (e.g. the design's name and the deviation figures).
    """
    target_V = np.asarray(target_V, dtype=float)
    V = np.asarray(V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    target_F = np.asarray(target_F, dtype=np.int64)
    distance = np.asarray(distance, dtype=float)
    if distance.shape != (len(V),):
        raise ValueError(f"distance must have one value per predicted vertex ({len(V)}), got {distance.shape}")
    diag = float(diagonal if diagonal is not None else np.linalg.norm(target_V.max(0) - target_V.min(0)))
    # both in the target's principal frame (largest extent along x, smallest along z), so the
    # camera sees the surface from above whatever its placement
    centre = target_V.mean(axis=0)
    _, _, Vt = np.linalg.svd(target_V - centre, full_matrices=False)
    if np.linalg.det(Vt) < 0:
        Vt[2] *= -1
    target_V = (target_V - centre) @ Vt.T
    V = (V - centre) @ Vt.T
    pct = 100.0 * distance / diag
    vmax = max(float(np.percentile(pct, 99)), 0.5)
    norm = Normalize(vmin=0.0, vmax=vmax)
    cmap = matplotlib.colormaps["viridis"]
    face_pct = pct[F].mean(axis=1)
    lo = np.minimum(target_V.min(0), V.min(0))
    hi = np.maximum(target_V.max(0), V.max(0))

    fig = Figure(figsize=(12.0, 5.6), dpi=dpi)
    FigureCanvasAgg(fig)
    a1 = fig.add_subplot(1, 2, 1, projection="3d")
    a2 = fig.add_subplot(1, 2, 2, projection="3d")
    grey = np.tile([0.78, 0.78, 0.80, 1.0], (len(target_F), 1))
    _view(a1, target_V, target_F, _shade(target_V, target_F, grey), lo, hi, "target")
    _view(a2, V, F, _shade(V, F, cmap(norm(face_pct))), lo, hi,
          f"prediction: deviation mean {pct.mean():.2f} %, p99 {np.percentile(pct, 99):.2f} %, "
          f"max {pct.max():.2f} %")
    sm = ScalarMappable(norm=norm, cmap=cmap)
    cb = fig.colorbar(sm, ax=[a1, a2], shrink=0.6, pad=0.04, location="right")
    cb.set_label("distance to the target, % of its bounding-box diagonal")
    ticks = np.linspace(0.0, vmax, 6)
    cb.set_ticks(ticks)
    cb.set_ticklabels([f"{t:.1f} %" for t in ticks])
    if title:
        fig.suptitle(title, fontsize=12)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": "ribbond"})
    return buf.getvalue()
