"""Ribbons to nozzle passes: lines of the nozzle's width side by side, in layers (§7).

A ribbon of width w_r is printed as L = max(1, round(w_r / nozzle)) lines of width w_r / L, offset
from its centerline, and its thickness τ as n = ⌈τ / max_layer_height⌉ layers of τ / n each, so
the plastic laid down has exactly the ribbon's cross-section w_r × τ. The passes snake: the lines of
a layer alternate direction, and the next layer runs the lines back in the opposite order, so each
pass starts next to where the previous one ended.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A corner's offset is lengthened by 1/cos(half the turn), at most by this factor.
_MAX_MITER = 2.0


@dataclass(frozen=True)
class RibbonPasses:
    """The passes of one ribbon in print order.

    Attributes
    ----------
    paths : one (k, 2) polyline per pass, mm.
    layer : (P,) the layer of each pass (0 = on the fabric).
    line_width, layer_height : of every pass, mm.
    """

    paths: list[np.ndarray]
    layer: np.ndarray
    line_width: float
    layer_height: float

    @property
    def entry(self) -> np.ndarray:
        return self.paths[0][0]

    @property
    def exit(self) -> np.ndarray:
        return self.paths[-1][-1]


def offset_polyline(points: np.ndarray, distance: float) -> np.ndarray:
    """``points`` (k, 2) moved ``distance`` mm to the left of the direction of travel (mitred)."""
    seg = np.diff(points, axis=0)
    seg /= np.maximum(np.linalg.norm(seg, axis=1), 1e-12)[:, None]
    tangent = np.vstack([seg[:1], seg[:-1] + seg[1:], seg[-1:]])
    norm = np.linalg.norm(tangent, axis=1)
    tangent = np.where(norm[:, None] > 1e-9, tangent / np.maximum(norm, 1e-12)[:, None],
                       np.vstack([seg[:1], seg])[: len(points)])
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    # miter: the offset at a corner keeps the distance from both segments
    cos_half = np.ones(len(points))
    cos_half[1:-1] = np.abs(np.einsum("kc,kc->k", tangent[1:-1], seg[1:]))
    scale = 1.0 / np.maximum(cos_half, 1.0 / _MAX_MITER)
    return points + distance * scale[:, None] * normal


def layer_plan(thickness: float, max_layer_height: float) -> tuple[int, float]:
    """(layers, layer height): the fewest equal layers no thicker than ``max_layer_height``."""
    n = max(1, int(np.ceil(thickness / max_layer_height - 1e-9)))
    return n, thickness / n


def line_plan(width: float, nozzle: float) -> tuple[int, float]:
    """(lines, line width): lines as wide as the nozzle or nearly, side by side over ``width``."""
    n = max(1, int(round(width / nozzle)))
    return n, width / n


def ribbon_passes(points: np.ndarray, width: float, thickness: float, nozzle: float,
                  max_layer_height: float) -> RibbonPasses:
    """The passes that print a ribbon along ``points`` (k, 2), from its first point.

    Parameters
    ----------
    points : (k, 2) the centerline, mm; width, thickness : w_r and τ, mm.
    nozzle : nozzle diameter; max_layer_height : mm.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
        raise ValueError(f"a ribbon needs a polyline of at least two points, got shape {pts.shape}")
    lines, line_width = line_plan(width, nozzle)
    layers, layer_height = layer_plan(thickness, max_layer_height)
    offsets = -0.5 * width + line_width * (np.arange(lines) + 0.5)
    rails = [offset_polyline(pts, o) for o in offsets]
    paths, layer = [], []
    p = 0
    for k in range(layers):
        order = range(lines) if k % 2 == 0 else range(lines - 1, -1, -1)
        for j in order:
            paths.append(rails[j] if p % 2 == 0 else rails[j][::-1])
            layer.append(k)
            p += 1
    return RibbonPasses(paths=paths, layer=np.asarray(layer), line_width=line_width,
                        layer_height=layer_height)


def mark_passes(center: np.ndarray, size: float, line_width: float) -> list[np.ndarray]:
    """A registration mark: a cross of two strokes of length ``size`` centred on ``center`` (2,)."""
    c = np.asarray(center, dtype=float)
    h = 0.5 * size
    return [np.array([c + [-h, 0.0], c + [h, 0.0]]), np.array([c + [0.0, -h], c + [0.0, h]])]
