"""Ribbons of a written design carried back onto the target, to be measured against exact geometry.

Only the folder's files are used (flat.obj, target.obj, design.json's ribbons): a ribbon segment's
midpoint is located in the flat triangle that holds it and carried to the target by that
triangle's affine map, its direction by the map's linear part.
"""

from __future__ import annotations

import igl
import numpy as np

from ribbond.design.folder import DesignFolder
from ribbond.design.surfaces import ExactCurvature


def _locate(points: np.ndarray, flat: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    P3 = np.column_stack([points, np.zeros(len(points))])
    V3 = np.column_stack([flat, np.zeros(len(flat))])
    _, face, closest = igl.point_mesh_squared_distance(P3, V3, F)
    c = F[face]
    bary = np.asarray(igl.barycentric_coordinates(np.ascontiguousarray(closest), np.ascontiguousarray(V3[c[:, 0]]),
                                                  np.ascontiguousarray(V3[c[:, 1]]), np.ascontiguousarray(V3[c[:, 2]])))
    return face.astype(np.int64), bary


def ribbon_segments_on_target(folder: DesignFolder, side: str | None = None
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ribbon segment carried onto the target: midpoints (q, 3), unit directions (q, 3) and
    flat lengths (q,); ``side`` "front"/"back" keeps one side's ribbons."""
    ribbons = [r for r in folder.design.ribbons or [] if side is None or r.side == side]
    if not ribbons:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    pts = [np.asarray(r.points) for r in ribbons]
    a = np.concatenate([p[:-1] for p in pts])
    b = np.concatenate([p[1:] for p in pts])
    mid, vec = 0.5 * (a + b), b - a
    flat, target, F = folder.flat_V[:, :2], folder.target_V, folder.target_F
    face, bary = _locate(mid, flat, F)
    T, X = flat[F[face]], target[F[face]]                               # (q, 3, 2), (q, 3, 3)
    D = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], axis=2)           # flat edge matrix (q, 2, 2)
    E = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=2)           # target edges (q, 3, 2)
    d3 = np.einsum("qij,qj->qi", E, np.linalg.solve(D, vec[:, :, None])[..., 0])
    d3 /= np.linalg.norm(d3, axis=1, keepdims=True)
    return np.einsum("qc,qcd->qd", bary, X), d3, np.linalg.norm(vec, axis=1)


def line_deviation_deg(directions: np.ndarray, exact: ExactCurvature) -> np.ndarray:
    """Angle (q,) between line directions (q, 3) and the exact k1 (projected on their tangent plane)."""
    n = exact.normal
    e = exact.direction1 - np.einsum("ij,ij->i", exact.direction1, n)[:, None] * n
    d = directions - np.einsum("ij,ij->i", directions, n)[:, None] * n
    c = np.abs(np.einsum("ij,ij->i", d, e)) / (np.linalg.norm(d, axis=1) * np.linalg.norm(e, axis=1))
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The ``q`` quantile of ``values`` weighted by ``weights``."""
    order = np.argsort(values)
    v, w = values[order], weights[order]
    cw = (np.cumsum(w) - 0.5 * w) / np.sum(w)
    return float(np.interp(q, cw, v))
