"""The ribbon-resolved model (issue 23, ``--fine``): every ribbon a strip of its own on the fabric.

A second opinion on the homogenized shell of ``rest_forms``: instead of averaging the pattern into
per-face rest forms, the flat domain is meshed finely enough to resolve each ribbon (``fine_mesh``:
``ACROSS`` rows of triangles across a ribbon, edges of w_r / ``ACROSS`` on and near the ribbons, graded
to ``2**LEVELS`` times that on the bare fabric far from them) and, per face,

- a ribbon face (its centroid inside a ribbon's rectangle: the centerline buffered by w_r / 2, flat
  ends) keeps the printed metric, Ā = I: the plastic was printed on the stretched fabric, is ~26×
  stiffer than it and does not contract by itself; it curls along the ribbon, B̄ = ±κ_r d dᵀ (+ on
  the front, as ``rest_forms``), and has the stiffness of fabric and plastic of the ribbon's τ;
- a bare face contracts by 1/s, Ā = I / s², B̄ = 0, with the fabric's stiffness alone.

The ribbons' own curvature κ_r is not the table's κ: the table gives the curvature a whole pattern
rolls into, ribbons, gaps and the fabric between the rows. ``calibrated_curvature`` finds κ_r by a
secant on a simulated coupon of the calibration pattern (§5, Fig. 5-6: staggered rows at μ2, ribbons
l_r long every μ1, the design's w_r) released along the same path (``release``), whose curvature is
measured by a circle fit of its middle (``coupon_curvature``), so that the coupon rolls into the
table's κ(τ, μ2). Solved at the table node nearest each ribbon's (τ, μ2) (one coupon per node the
layout uses, cached per process) and applied as the ratio κ_r / κ there to the table's κ at the
ribbon's own (τ, μ2). The two models then
agree on coupons by construction; whether they agree on real layouts is the question the bench asks.

Measured so far (τ 0.6 mm, μ2 6 mm, front table κ 0.0290 /mm): with ``Material()`` (fabric 1 MPa × 0.4 mm)
the coupon hardly answers to κ_r (released in 5 steps: κ_r 0.0068 → 0.097 /mm, 0.0290 → 0.124; in 10
steps: 0 → 0.112, 0.06 → 0.138): the misfit between the unshrinking ribbons and the fabric contracting by
1/s buckles the mid-surface shell by itself, so the secant asks for κ_r < 0 and the calibration fails
(``calibrated_curvature`` raises, giving what it reached). With the fabric 20× softer in plane it
answers (κ_r 0.02 → 0.0138, 0.04 → 0.0221). Either way the last release steps do not converge: the
fabric squeezed at the ribbons' ends is compressed toward the limit point of the
St.Venant-Kirchhoff membrane (edges at 0.64 of their rest length), where its energy stops resisting.
A bare fabric that wrinkles instead (Pipkin's tension-field relaxation of the same law, tried with
finite-difference-checked derivatives and not kept) makes it worse: the coupon crumples (κ 0.25 and
0.22 /mm at κ_r 0.01 and 0.03; fabric edges down to 2 % of their rest length), its strips between
the rows shortening by leaving the ribbons' surface. On one mid-surface the fabric pulls the ribbons
at their middle, not at their underside, so the bilayer's moment is missing and the misfit can only
buckle: the model needs the fabric's measured tension at s (a tensile test) or a layered sheet.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ribbond.design.format import Ribbon
from ribbond.design.remesh import delaunay_inside
from ribbond.design.thickness import CurvatureTable, table_curvature

from .release import Sheet, release
from .rest_forms import _outline, ribbon_samples

__all__ = ["FineMesh", "fine_mesh", "ribbon_resolved_sheet", "calibrated_curvature", "coupon_sheet",
           "coupon_curvature", "CALIBRATION_MU1", "CALIBRATION_LENGTH"]

#: Rows of triangles across a ribbon (the issue asks for at least 3).
ACROSS = 3
#: Vertices along a ribbon every ALONG × the edge across (triangles of aspect ~2: the ribbon bends
#: along its length on a radius of tens of mm, and resolving its width is what costs).
ALONG = 2.0
#: Levels of grading: bare fabric far from the ribbons has edges 2**LEVELS × the ribbons'.
LEVELS = 3
#: Distance from the ribbons, × the ribbon edge, at which each coarser level starts (level k beyond
#: GRADE × (2**k − 1) edges): neighbouring faces differ in size by a factor of two at most.
GRADE = 1.0
#: The calibration pattern's μ1 and l_r, mm (``ribbond.calibration.spec``: Fig. 5's μ1, the paper's l_r).
CALIBRATION_MU1 = 22.5
CALIBRATION_LENGTH = 15.0
#: The coupon: this many motifs along the ribbons, rows across.
COUPON_MOTIFS, COUPON_ROWS = 3, 5
#: Release steps of a coupon, and the secant's relative tolerance and evaluation cap.
COUPON_STEPS = 5
CALIBRATION_RTOL = 2e-3
CALIBRATION_EVALS = 6


@dataclass(frozen=True)
class FineMesh:
    """A triangulation of the flat domain resolving the ribbons.

    Attributes
    ----------
    uv : (n, 2) positions, mm; F : (m, 3) faces, counter-clockwise.
    ribbon : (m,) the ribbon holding each face's centroid, −1 on bare fabric.
    direction : (m, 2) unit ribbon direction at ribbon faces ((1, 0) on bare ones).
    edge : the edge length on the ribbons, mm.
    """

    uv: np.ndarray
    F: np.ndarray
    ribbon: np.ndarray
    direction: np.ndarray
    edge: float


def _ribbon_points(ribbons: Sequence[Ribbon], width: float, h: float) -> np.ndarray:
    """(k, 2) points in rows along each ribbon: ACROSS + 1 lines from −w/2 to +w/2, every ALONG × h or closer."""
    s = ribbon_samples(ribbons, ALONG * h)
    normal = np.column_stack([-s.tangent[:, 1], s.tangent[:, 0]])
    offsets = width * (np.arange(ACROSS + 1) / ACROSS - 0.5)
    return (s.xy[:, None, :] + offsets[None, :, None] * normal[:, None, :]).reshape(-1, 2)


def _lattice(lo: np.ndarray, hi: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A triangular lattice of spacing h over [lo, hi]: points (k, 2) and their integer coordinates
    (i, j) along a = (h, 0), b = (h/2, h√3/2); the points with i, j both ≡ 0 mod 2^k form the
    lattice of spacing 2^k h."""
    dy = h * np.sqrt(3.0) / 2.0
    j = np.arange(int(np.ceil((hi[1] - lo[1]) / dy)) + 1)
    i0 = -(j // 2) - 1                                  # the rows lean: start far enough left
    ncol = int(np.ceil((hi[0] - lo[0]) / h)) + 3
    I = i0[:, None] + np.arange(ncol)[None, :]
    J = np.broadcast_to(j[:, None], I.shape)
    x = lo[0] + I * h + 0.5 * h * J
    y = lo[1] + J * dy
    keep = (x >= lo[0] - h) & (x <= hi[0] + h)
    return np.column_stack([x[keep], y[keep]]), I[keep], J[keep]


def _level(distance: np.ndarray, h: float) -> np.ndarray:
    """The grading level (0 … LEVELS) at a distance from the ribbons."""
    return np.clip(np.floor(np.log2(1.0 + distance / (GRADE * h))), 0, LEVELS).astype(np.int64)


def _boundary_points(outline: shapely.Geometry, h: float, tree: cKDTree | None) -> np.ndarray:
    """Points along every ring of the outline every h, kept where the level there allows them."""
    rings = []
    for poly in getattr(outline, "geoms", [outline]):
        rings += [poly.exterior] + list(poly.interiors)
    out = []
    for ring in rings:
        n = max(int(np.ceil(ring.length / h)), 3)
        pts = shapely.get_coordinates(shapely.line_interpolate_point(ring, np.arange(n) * ring.length / n))
        lev = _level(tree.query(pts)[0], h) if tree is not None else np.full(n, LEVELS)
        out.append(pts[np.arange(n) % (2 ** lev) == 0])
    return np.vstack(out)


def _dedupe(P: np.ndarray, r: float) -> np.ndarray:
    """P without the later of any two points closer than r (ribbons that touch, the outline)."""
    pairs = cKDTree(P).query_pairs(r, output_type="ndarray")
    drop = np.zeros(len(P), dtype=bool)
    drop[np.maximum(pairs[:, 0], pairs[:, 1])] = True
    return P[~drop]


def _ribbon_polygons(ribbons: Sequence[Ribbon], width: float) -> np.ndarray:
    """(R,) each ribbon's rectangle: its centerline buffered by w/2 with flat ends."""
    pts = [np.asarray(r.points, dtype=float) for r in ribbons]
    lines = shapely.linestrings(np.vstack(pts), indices=np.repeat(np.arange(len(pts)), [len(p) for p in pts]))
    return shapely.buffer(lines, 0.5 * width, cap_style="flat", join_style="mitre")


def fine_mesh(uv: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], ribbon_width: float) -> FineMesh:
    """Triangulate the flat domain of (uv (n, 2), F (m, 3)) resolving ``ribbons`` (module docstring).

    Each ribbon gets ACROSS + 1 lines of vertices along it from edge to edge (so ACROSS rows of
    triangles across), the bare fabric nested triangular lattices coarsening with the distance from
    the ribbons (``_level``), the outline its own samples; all Delaunay-triangulated, faces outside
    the outline dropped.
    """
    outline = _outline(uv, F)
    h = ribbon_width / ACROSS
    lo, hi = np.asarray(outline.bounds[:2]), np.asarray(outline.bounds[2:])
    rib = _ribbon_points(ribbons, ribbon_width, h) if ribbons else np.zeros((0, 2))
    rib = rib[shapely.contains_xy(outline, rib[:, 0], rib[:, 1])]
    tree = cKDTree(rib) if len(rib) else None
    P, I, J = _lattice(lo, hi, h)
    P, I, J = _cut(P, I, J, outline, h, ribbons, ribbon_width, tree)
    edge = _boundary_points(outline, h, tree)
    pts = _dedupe(np.vstack([edge, rib, P]), 0.3 * h)
    pts, T = delaunay_inside(pts, outline)
    which, direction = _face_ribbons(pts[T].mean(axis=1), ribbons, ribbon_width)
    return FineMesh(uv=pts, F=T, ribbon=which, direction=direction, edge=h)


def _cut(P: np.ndarray, I: np.ndarray, J: np.ndarray, outline: shapely.Geometry, h: float,
         ribbons: Sequence[Ribbon], width: float, tree: cKDTree | None):
    """The lattice points inside the outline, clear of it and of the ribbons, kept
    where their level's sublattice holds them."""
    inside = shapely.contains_xy(outline, P[:, 0], P[:, 1])
    P, I, J = P[inside], I[inside], J[inside]
    clear = shapely.distance(outline.boundary, shapely.points(P)) > 0.5 * h
    if ribbons:
        # clear of the Delaunay circles on the ribbon's edge (its vertices ALONG × h apart), so that
        # the triangulation keeps the rectangle's sides as edges
        band = shapely.union_all(shapely.buffer(_ribbon_polygons(ribbons, width), 0.6 * ALONG * h))
        shapely.prepare(band)
        clear &= ~shapely.contains_xy(band, P[:, 0], P[:, 1])
    P, I, J = P[clear], I[clear], J[clear]
    lev = _level(tree.query(P)[0], h) if tree is not None else np.full(len(P), LEVELS)
    step = 2 ** lev
    on = (I % step == 0) & (J % step == 0)
    return P[on], I[on], J[on]


def _face_ribbons(centroid: np.ndarray, ribbons: Sequence[Ribbon], width: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(m,) the ribbon whose rectangle holds each centroid (−1: none; the first where two overlap)
    and (m, 2) the direction of its nearest centerline sample there."""
    m = len(centroid)
    which = np.full(m, -1, dtype=np.int64)
    direction = np.tile([1.0, 0.0], (m, 1))
    if not ribbons:
        return which, direction
    tree = shapely.STRtree(_ribbon_polygons(ribbons, width))
    face, rid = tree.query(shapely.points(centroid), predicate="within")
    first = np.unique(face, return_index=True)[1]
    which[face[first]] = rid[first]
    s = ribbon_samples(ribbons, 0.25 * width)
    on = np.flatnonzero(which >= 0)
    # the nearest sample of the face's own ribbon: search a few and take the first of that ribbon
    k = min(8, len(s.xy))
    _, idx = cKDTree(s.xy).query(centroid[on], k=k)
    idx = idx.reshape(len(on), k)
    mine = s.ribbon[idx] == which[on][:, None]
    pick = idx[np.arange(len(on)), np.argmax(mine, axis=1)]
    direction[on] = s.tangent[pick]
    return which, direction


def coupon_pattern(mu2: float, thickness: float, width: float, side: str = "front"
                   ) -> tuple[list[Ribbon], tuple[float, float]]:
    """The calibration pattern (§5): COUPON_ROWS staggered rows every μ2 (the first at μ2/2), ribbons
    CALIBRATION_LENGTH long every CALIBRATION_MU1 along each row, every other row shifted by μ1/2,
    over COUPON_MOTIFS motifs; the ribbons and the coupon's size (X, Y), mm."""
    mu1, lr = CALIBRATION_MU1, CALIBRATION_LENGTH
    X, Y = COUPON_MOTIFS * mu1, COUPON_ROWS * mu2
    out = []
    for j in range(COUPON_ROWS):
        y = (j + 0.5) * mu2
        x0 = np.arange(-mu1, X + mu1, mu1) + 0.5 * (mu1 - lr) + 0.5 * mu1 * (j % 2)
        a, b = np.maximum(x0, 0.0), np.minimum(x0 + lr, X)
        for s, e in zip(a[b - a >= 2 * width], b[b - a >= 2 * width]):      # no stubs at the ends
            out.append(Ribbon(side=side, points=[(float(s), y), (float(e), y)], thickness=thickness,
                              kappa1=0.0, spacing=(mu1, mu2)))
    return out, (X, Y)


def _rectangle(size: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Two triangles covering [0, X] × [0, Y] (the coupon's outline; ``fine_mesh`` meshes it anew)."""
    X, Y = size
    return np.array([[0.0, 0.0], [X, 0.0], [X, Y], [0.0, Y]]), np.array([[0, 1, 2], [0, 2, 3]])


def _sheet(mesh: FineMesh, ribbons: Sequence[Ribbon], kappa_r: np.ndarray, prestretch: float, material) -> Sheet:
    """The printed sheet on ``mesh`` with ribbon r's own rest curvature ``kappa_r[r]`` (signed)."""
    from .predict import Material                   # predict imports this module lazily
    material = material or Material()
    m = len(mesh.F)
    on = mesh.ribbon >= 0
    tau = np.zeros(m)
    kap = np.zeros(m)
    if len(ribbons):
        thick = np.array([r.thickness for r in ribbons])
        tau[on] = thick[mesh.ribbon[on]]
        kap[on] = np.asarray(kappa_r)[mesh.ribbon[on]]
    d = mesh.direction
    abar = np.where(on[:, None, None], np.eye(2)[None], np.eye(2)[None] / prestretch ** 2)
    bbar = kap[:, None, None] * d[:, :, None] * d[:, None, :]
    Ds, Db = material.stiffness(on.astype(float), tau)
    return Sheet(uv=mesh.uv, F=mesh.F, abar=abar, bbar=bbar, stretch=Ds, bend=Db, nu=material.poisson)


def coupon_curvature(X: np.ndarray, uv: np.ndarray, F: np.ndarray, size: tuple[float, float]) -> float:
    """The curvature, 1/mm, of a released coupon (X (n, 3) over its flat uv (n, 2), F) rolled along x
    (``coupon_circle``)."""
    return 1.0 / coupon_circle(X, uv, F, size)[0]


def coupon_circle(X: np.ndarray, uv: np.ndarray, F: np.ndarray, size: tuple[float, float]) -> tuple[float, float]:
    """(radius, the largest distance of a fitted vertex from the circle), mm, of a released coupon
    rolled along x: the vertices of its middle (the central half each way), projected along the
    cylinder's axis (the mean image of the flat y direction there), fitted by a circle (least
    squares, Kåsa)."""
    Xs, Ys = size
    c = uv[F].mean(axis=1)
    inner = (np.abs(c[:, 0] - Xs / 2) < Xs / 4) & (np.abs(c[:, 1] - Ys / 2) < Ys / 4)
    e = np.stack([X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]], axis=2)
    u = np.stack([uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]], axis=2)
    axis = (e @ np.linalg.inv(u) @ np.array([0.0, 1.0]))[inner].mean(axis=0)
    axis /= np.linalg.norm(axis)
    mid = (np.abs(uv[:, 0] - Xs / 2) < Xs / 4) & (np.abs(uv[:, 1] - Ys / 2) < Ys / 4)
    P = X[mid] - X[mid].mean(axis=0)
    P -= np.outer(P @ axis, axis)
    b1 = np.cross(axis, P[np.argmax(np.linalg.norm(P, axis=1))])
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(axis, b1)
    x, y = P @ b1, P @ b2
    cx, cy, k0 = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x ** 2 + y ** 2, rcond=None)[0]
    radius = float(np.sqrt(k0 + cx ** 2 / 4 + cy ** 2 / 4))
    return radius, float(np.abs(np.hypot(x - cx / 2, y - cy / 2) - radius).max())


_CALIBRATED: dict[tuple, float] = {}


def _coupon_response(mesh: FineMesh, ribbons: list[Ribbon], size: tuple[float, float], kappa_r: float,
                     prestretch: float, material) -> tuple[float, bool]:
    """The coupon's measured curvature with rest curvature κ_r on every ribbon, and whether it converged."""
    r = release(_sheet(mesh, ribbons, np.full(len(ribbons), kappa_r), prestretch, material), steps=COUPON_STEPS)
    return coupon_curvature(r.X, mesh.uv, mesh.F, size), r.converged


def calibrated_curvature(table: CurvatureTable, side: str, thickness: float, mu2: float, *, prestretch: float,
                         ribbon_width: float, material=None) -> float:
    """κ_r > 0, 1/mm: the ribbons' own rest curvature with which the coupon of the calibration pattern
    (``coupon_pattern``) at (τ, μ2) rolls into the table's κ(τ, μ2) of ``side`` (a secant on the
    coupon's measured curvature, from κ_r = κ; cached per argument).

    Raises
    ------
    ValueError
        for a non-positive thickness or spacing, or when the coupon's curvature cannot be brought to the
        table's within CALIBRATION_EVALS releases (the message gives the curvatures it reached).
    """
    if not (np.isfinite(thickness) and thickness > 0):
        raise ValueError(f"calibration: thickness must be > 0 mm, got {thickness!r}")
    if not (np.isfinite(mu2) and mu2 > ribbon_width):
        raise ValueError(f"calibration: mu2 = {mu2!r} mm must exceed ribbon_width = {ribbon_width} mm")
    key = (table.name, side, round(float(thickness), 4), round(float(mu2), 3), float(prestretch),
           float(ribbon_width), repr(material))
    if key in _CALIBRATED:
        return _CALIBRATED[key]
    goal = float(table_curvature(table, side, np.array([thickness]), np.array([mu2]))[0])
    ribbons, size = coupon_pattern(mu2, thickness, ribbon_width)
    uv, F = _rectangle(size)
    mesh = fine_mesh(uv, F, ribbons, ribbon_width)
    tried: list[tuple[float, float]] = []
    k = goal
    for _ in range(CALIBRATION_EVALS):
        measured, _ok = _coupon_response(mesh, ribbons, size, k, prestretch, material)
        tried.append((k, measured))
        if abs(measured - goal) <= CALIBRATION_RTOL * goal:
            _CALIBRATED[key] = k
            return k
        if len(tried) == 1:
            k = k * goal / measured                      # the response through the origin
        else:
            (k0, m0), (k1, m1) = tried[-2], tried[-1]
            if abs(m1 - m0) <= CALIBRATION_RTOL * goal:
                break                                    # the coupon does not answer to κ_r
            k = k1 + (goal - m1) * (k1 - k0) / (m1 - m0)
        if not (np.isfinite(k) and 0 < k < 20 * goal):
            break
    raise ValueError(f"calibration of the ribbon-resolved model failed at τ = {thickness:g} mm, μ2 = {mu2:g} mm "
                     f"({side}): the coupon must roll into κ = {goal:.4g} /mm; rest curvatures κ_r → measured: "
                     + ", ".join(f"{a:.4g} → {b:.4g}" for a, b in tried))


def _check_layout(uv: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], prestretch: float,
                  ribbon_width: float) -> tuple[np.ndarray, np.ndarray]:
    uv = np.asarray(uv, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    if uv.ndim != 2 or uv.shape[1] != 2 or not np.all(np.isfinite(uv)):
        raise ValueError(f"uv must be a finite (n, 2) array, got shape {uv.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or F.min() < 0 or F.max() >= len(uv):
        raise ValueError(f"F must be an (m, 3) array of vertex indices 0..{len(uv) - 1}, got shape {F.shape}")
    if not (np.isfinite(prestretch) and prestretch > 1):
        raise ValueError(f"prestretch must be > 1, got {prestretch!r}")
    if not (np.isfinite(ribbon_width) and ribbon_width > 0):
        raise ValueError(f"ribbon_width must be > 0, got {ribbon_width!r}")
    for i, r in enumerate(ribbons):
        p = np.asarray(r.points, dtype=float)
        if not np.all(np.isfinite(p)) or np.linalg.norm(np.diff(p, axis=0), axis=1).sum() <= 0:
            raise ValueError(f"ribbon {i}: its centerline must be finite and of positive length")
    return uv, F


def ribbon_resolved_sheet(uv: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], *, prestretch: float,
                          ribbon_width: float, table: CurvatureTable, material=None,
                          calibrate: bool = True) -> Sheet:
    """The printed sheet with every ribbon resolved (module docstring).

    Parameters
    ----------
    uv : (n, 2) the flat surface, mm; F : (m, 3) its faces (only its domain is used: it is meshed anew).
    ribbons : the ribbons as placed; prestretch : s; ribbon_width : w_r, mm; table : the curvature table.
    material : ``predict.Material`` (default ``Material()``).
    calibrate : κ_r from coupons (``calibrated_curvature``, at the table node nearest each ribbon's
        (τ, μ2), as a ratio to the table's κ there); False: κ_r = the table's κ (the uncalibrated model).

    Returns
    -------
    Sheet on the fine mesh (``fine_mesh``): ribbon faces Ā = I, B̄ = ±κ_r d dᵀ, fabric + plastic
    stiffness; bare faces Ā = I/s², B̄ = 0, fabric stiffness.

    Raises
    ------
    ValueError
        for bad arrays or parameters (named), or a calibration that fails (``calibrated_curvature``).
    """
    uv, F = _check_layout(uv, F, ribbons, prestretch, ribbon_width)
    mesh = fine_mesh(uv, F, ribbons, ribbon_width)
    kappa_r = np.zeros(len(ribbons))
    if ribbons:
        tau = np.array([r.thickness for r in ribbons], dtype=float)
        mu2 = np.array([r.spacing[1] for r in ribbons], dtype=float)
        front = np.array([r.side == "front" for r in ribbons])
        kf = table_curvature(table, "front", tau, mu2)
        kb = table_curvature(table, "back", tau, mu2)
        kappa_r = np.where(front, kf, -kb)
        if calibrate:
            kappa_r *= _calibration_ratio(table, tau, mu2, front, prestretch, ribbon_width, material)
    return _sheet(mesh, ribbons, kappa_r, prestretch, material)


def _calibration_ratio(table: CurvatureTable, tau: np.ndarray, mu2: np.ndarray, front: np.ndarray,
                       prestretch: float, ribbon_width: float, material) -> np.ndarray:
    """(R,) κ_r / κ at the table node nearest each ribbon's (τ, μ2) and side: one coupon per node used."""
    tt, ss = np.asarray(table.thickness), np.asarray(table.spacing)
    i = np.abs(np.clip(tau, tt[0], tt[-1])[:, None] - tt[None, :]).argmin(axis=1)
    j = np.abs(np.clip(mu2, ss[0], ss[-1])[:, None] - ss[None, :]).argmin(axis=1)
    nodes, inverse = np.unique(np.column_stack([i, j, front]), axis=0, return_inverse=True)
    ratio = np.empty(len(nodes))
    for n, (a, b, f) in enumerate(nodes):                 # one coupon per node the layout uses
        side = "front" if f else "back"
        goal = float(table_curvature(table, side, tt[a:a + 1], ss[b:b + 1])[0])
        ratio[n] = calibrated_curvature(table, side, float(tt[a]), float(ss[b]), prestretch=prestretch,
                                        ribbon_width=ribbon_width, material=material) / goal
    return ratio[inverse.ravel()]
