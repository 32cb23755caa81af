"""A uniform triangulation of the flat surface at the resolution the stripe patterns need.

A stripe period must span a few edges (KCPS15 §5), and needs no more: the design mesh may be far
coarser (a few thousand faces over the layout) or far finer (160,000 faces, 20 edges per period)
than that. The stripe patterns are therefore computed on a fresh triangulation of the flat domain
with edges of one chosen length: the outline resampled at that spacing, a triangular lattice inside
it, Delaunay-triangulated, faces outside the outline dropped. Fields of the design mesh reach its
vertices by barycentric interpolation (the flat map is piecewise linear, so nothing is lost that the
stripes could resolve).
"""

from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np
import shapely
from scipy.spatial import Delaunay

#: Boundary vertices where the outline turns by more than this are kept, so corners stay sharp.
_CORNER_DEG = 20.0

#: Faces with less area than this × their longest edge² are dropped: Delaunay joins three outline
#: samples that are on one line but for rounding (a flattened straight edge wobbles by ~1e-7 mm)
#: into a sliver inside the outline; the lattice's own faces have ≈ 0.43, faces at the outline ≥ 0.05.
_SLIVER = 1e-3


@dataclass(frozen=True)
class FlatRemesh:
    """The flat domain triangulated anew, with where each new vertex and face lies in the design mesh.

    Attributes
    ----------
    uv : (p, 2) vertex positions, mm; F : (t, 3) faces, counter-clockwise.
    face : (p,) the design face holding each vertex; bary : (p, 3) its barycentric coordinates there.
    parent : (t,) the design face holding each face's centroid.
    spacing : the target edge length, mm.
    """

    uv: np.ndarray
    F: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    parent: np.ndarray
    spacing: float
    design_F: np.ndarray

    def vertex_values(self, values: np.ndarray) -> np.ndarray:
        """Design-vertex ``values`` (n,) or (n, k) interpolated at the new vertices."""
        v = np.asarray(values, dtype=float)[self.design_F[self.face]]       # (p, 3, …)
        return np.einsum("pc,pc...->p...", self.bary, v)


def locate(points: np.ndarray, uv: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The face of (uv, F) nearest to (holding) each point (k, 2), and the barycentric coordinates
    (k, 3) there."""
    P3 = np.column_stack([points, np.zeros(len(points))])
    V3 = np.column_stack([uv, np.zeros(len(uv))])
    _, face, closest = igl.point_mesh_squared_distance(P3, V3, F)
    c = F[face]
    bary = igl.barycentric_coordinates(np.ascontiguousarray(closest), np.ascontiguousarray(V3[c[:, 0]]),
                                       np.ascontiguousarray(V3[c[:, 1]]), np.ascontiguousarray(V3[c[:, 2]]))
    bary = np.clip(np.asarray(bary), 0.0, None)
    return face.astype(np.int64), bary / bary.sum(axis=1, keepdims=True)


def _outline_samples(ring: np.ndarray, spacing: float) -> np.ndarray:
    """Points along the closed polyline ``ring`` (k, 2) every ``spacing`` or so, corners kept."""
    closed = np.vstack([ring, ring[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    count = max(int(np.ceil(total / spacing)), 3)
    t = np.linspace(0.0, total, count, endpoint=False)
    # keep the outline's own corners
    e_in = ring - np.roll(ring, 1, axis=0)
    e_out = np.roll(ring, -1, axis=0) - ring
    turn = np.degrees(np.abs(np.arctan2(e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0],
                                        np.einsum("kc,kc->k", e_in, e_out))))
    corners = s[:-1][turn > _CORNER_DEG]
    t = np.union1d(t, corners)
    # drop uniform samples that crowd a corner
    near = np.abs(t[:, None] - corners[None, :]).min(axis=1, initial=np.inf) if len(corners) else np.full(len(t), np.inf)
    t = t[(near > 0.4 * spacing) | np.isin(t, corners)]
    return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])


def delaunay_inside(points: np.ndarray, outline: shapely.Geometry) -> tuple[np.ndarray, np.ndarray]:
    """The Delaunay triangles of ``points`` (k, 2) whose centroid lies in ``outline``, slivers
    (area ≤ ``_SLIVER`` × longest edge²) dropped, counter-clockwise, the unused points dropped:
    (points (k', 2), triangles (t, 3))."""
    tri = Delaunay(points).simplices.astype(np.int64)
    centroid = points[tri].mean(axis=1)
    a, b = points[tri[:, 1]] - points[tri[:, 0]], points[tri[:, 2]] - points[tri[:, 0]]
    signed = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    longest = np.linalg.norm(points[tri] - points[np.roll(tri, 1, axis=1)], axis=2).max(axis=1)
    keep = shapely.contains_xy(outline, centroid[:, 0], centroid[:, 1]) & (np.abs(signed) > _SLIVER * longest ** 2)
    tri, signed = tri[keep], signed[keep]
    tri[signed < 0] = tri[signed < 0][:, [0, 2, 1]]
    used = np.unique(tri)
    index = np.full(len(points), -1, dtype=np.int64)
    index[used] = np.arange(len(used))
    return points[used], index[tri]


def remesh_flat(uv: np.ndarray, F: np.ndarray, boundary: np.ndarray, spacing: float) -> FlatRemesh:
    """Triangulate the flat domain of (uv (n, 2), F (m, 3)) with edges of about ``spacing`` mm.

    Parameters
    ----------
    boundary : (b,) the design mesh's boundary loop (vertex indices, in order).
    """
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be a positive length, got {spacing!r}")
    ring = uv[boundary]
    outline = shapely.Polygon(ring)
    if not outline.is_valid:
        outline = shapely.make_valid(outline)
    shapely.prepare(outline)
    edge = _outline_samples(ring, spacing)
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    dy = spacing * np.sqrt(3.0) / 2.0
    ys = np.arange(lo[1] + 0.5 * dy, hi[1], dy)
    xs = np.arange(lo[0], hi[0] + spacing, spacing)
    gx, gy = np.meshgrid(xs, ys)
    gx = gx + 0.5 * spacing * (np.arange(len(ys)) % 2)[:, None]              # triangular lattice
    lattice = np.column_stack([gx.ravel(), gy.ravel()])
    inside = shapely.contains_xy(outline, lattice[:, 0], lattice[:, 1])
    lattice = lattice[inside]
    far = shapely.distance(outline.boundary, shapely.points(lattice)) > 0.5 * spacing
    points = np.vstack([edge, lattice[far]])
    points, tri = delaunay_inside(points, outline)
    face, bary = locate(points, uv, F)
    parent, _ = locate(points[tri].mean(axis=1), uv, F)
    return FlatRemesh(uv=points, F=tri, face=face, bary=bary, parent=parent, spacing=float(spacing),
                      design_F=np.asarray(F, dtype=np.int64))
