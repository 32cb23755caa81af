"""Parametric target surfaces built from scratch: the test, example and benchmark meshes.

Every function returns ``(V, F)``: ``V`` (n, 3) float64 vertex positions in mm and ``F`` (m, 3)
int64 faces, a consistently oriented topological disk. The winding gives the normal n stated in
each docstring, because the sign of κ1 (front or back) follows from it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay


def grid(nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated unit square [0, 1]², counter-clockwise seen from +z.

    Parameters
    ----------
    nu, nv : int
        cells along u and v (≥ 1).

    Returns
    -------
    UV : (nu+1)(nv+1) × 2 parameter values; F : 2 nu nv × 3 faces. Diagonals alternate in a
    checkerboard so the triangulation has no preferred direction.
    """
    if nu < 1 or nv < 1:
        raise ValueError(f"grid needs at least one cell each way, got {nu} × {nv}")
    u, v = np.meshgrid(np.linspace(0.0, 1.0, nu + 1), np.linspace(0.0, 1.0, nv + 1), indexing="ij")
    UV = np.column_stack([u.ravel(), v.ravel()])
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()      # (i, j), (i+1, j)
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()        # (i+1, j+1), (i, j+1)
    flip = ((np.add.outer(np.arange(nu), np.arange(nv))) % 2 == 1).ravel()
    t1 = np.where(flip[:, None], np.column_stack([a, b, d]), np.column_stack([a, b, c]))
    t2 = np.where(flip[:, None], np.column_stack([b, c, d]), np.column_stack([a, c, d]))
    return UV, np.vstack([t1, t2]).astype(np.int64)


def disk(rings: int) -> tuple[np.ndarray, np.ndarray]:
    """A triangulated unit disk of concentric rings (ring k holds 6k points), CCW from +z.

    Returns
    -------
    P : n × 2 points (n = 1 + 3 rings (rings + 1)); F : m × 3 faces (Delaunay).
    """
    if rings < 1:
        raise ValueError(f"disk needs at least one ring, got {rings}")
    k = np.repeat(np.arange(1, rings + 1), 6 * np.arange(1, rings + 1))
    start = np.concatenate([[0], np.cumsum(6 * np.arange(1, rings + 1))])[:-1]
    j = np.arange(k.size) - np.repeat(start, 6 * np.arange(1, rings + 1))
    phi = 2 * np.pi * j / (6 * k) + 0.5 * (k % 2) * np.pi / (6 * k)   # stagger odd rings
    rho = k / rings
    P = np.vstack([[0.0, 0.0], np.column_stack([rho * np.cos(phi), rho * np.sin(phi)])])
    F = Delaunay(P).simplices.astype(np.int64)
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[cw] = F[cw][:, [0, 2, 1]]
    return P, F


def irregular_grid(nu: int, nv: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A scan-like triangulation of [0, 1]²: the grid's interior vertices moved by up to 0.2 of a
    cell each way and every cell's diagonal drawn at random (valences 4 to 8), CCW from +z."""
    rng = np.random.default_rng(seed)
    UV, F = grid(nu, nv)
    inner = (UV > 0).all(axis=1) & (UV < 1).all(axis=1)
    UV[inner] += rng.uniform(-0.2, 0.2, (inner.sum(), 2)) / np.array([nu, nv])
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    flip = rng.random(nu * nv) < 0.5
    t1 = np.where(flip[:, None], np.column_stack([a, b, d]), np.column_stack([a, b, c]))
    t2 = np.where(flip[:, None], np.column_stack([b, c, d]), np.column_stack([a, c, d]))
    return UV, np.vstack([t1, t2]).astype(np.int64)


def irregular_disk(rings: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``disk`` with its interior points moved by up to 0.3 of a ring spacing each way,
    Delaunay-triangulated again (the boundary circle kept), CCW from +z."""
    rng = np.random.default_rng(seed)
    P, _ = disk(rings)
    inner = np.hypot(P[:, 0], P[:, 1]) < 1 - 0.5 / rings
    P[inner] += rng.uniform(-0.3, 0.3, (inner.sum(), 2)) / rings
    F = Delaunay(P).simplices.astype(np.int64)
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    cw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    F[cw] = F[cw][:, [0, 2, 1]]
    return P, F


def cylinder_patch(radius: float = 40.0, angle_deg: float = 120.0, height: float = 60.0,
                   n_around: int = 40, n_along: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A patch of a cylinder about the z-axis; n points away from the axis (κ1 = +1/radius).

    The circumference (the direction of κ1) spans ``angle_deg`` around the axis; the axis is
    along z, over ``height``.
    """
    UV, F = grid(n_around, n_along)
    t = np.radians(angle_deg) * (UV[:, 0] - 0.5)
    V = np.column_stack([radius * np.cos(t), radius * np.sin(t), height * (UV[:, 1] - 0.5)])
    return V, F   # (∂/∂t) × (∂/∂z) is radial outward, so the grid's CCW winding gives n outward


def torus_patch(R: float = 50.0, r: float = 20.0, u_deg: tuple[float, float] = (0.0, 90.0),
                v_deg: tuple[float, float] = (-45.0, 45.0), nu: int = 60,
                nv: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """A patch of the torus ((R + r cos v) cos u, (R + r cos v) sin u, r sin v); n outward.

    v = 0 is the outer equator, where the tube's curvature 1/r is κ1 and 1/(R + r) is κ2.
    """
    UV, F = grid(nu, nv)
    u = np.radians(u_deg[0] + (u_deg[1] - u_deg[0]) * UV[:, 0])
    v = np.radians(v_deg[0] + (v_deg[1] - v_deg[0]) * UV[:, 1])
    rho = R + r * np.cos(v)
    V = np.column_stack([rho * np.cos(u), rho * np.sin(u), r * np.sin(v)])
    return V, F   # ∂/∂u × ∂/∂v points away from the tube's core circle


def sphere_cap(radius: float = 60.0, half_angle_deg: float = 30.0,
               rings: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """The cap of a sphere within ``half_angle_deg`` of its north pole; n outward (κ = +1/radius)."""
    P, F = disk(rings)
    polar = np.radians(half_angle_deg) * np.hypot(P[:, 0], P[:, 1])
    az = np.arctan2(P[:, 1], P[:, 0])
    V = radius * np.column_stack([np.sin(polar) * np.cos(az), np.sin(polar) * np.sin(az),
                                  np.cos(polar)])
    return V, F


def saddle(size: float = 80.0, kappa_x: float = 1.0 / 40.0, kappa_y: float = 1.0 / 100.0,
           rings: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """The disk of diameter ``size`` on z = (κx x² − κy y²) / 2 (n up).

    At the centre the surface is a valley along x and a ridge along y; with the normal up, the
    signed curvatures (design-format.md: positive where the surface bulges toward n) are −κx
    along x and +κy along y (negative Gaussian curvature); with κx ≠ κy the direction of largest
    |κ| is defined everywhere near it.
    """
    P, F = disk(rings)
    xy = 0.5 * size * P
    z = 0.5 * (kappa_x * xy[:, 0] ** 2 - kappa_y * xy[:, 1] ** 2)
    return np.column_stack([xy, z]), F


def plane_disk(diameter: float = 80.0, rings: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A flat disk in the plane z = 0 (n = +z): every point umbilic, κ = 0."""
    P, F = disk(rings)
    return np.column_stack([0.5 * diameter * P, np.zeros(len(P))]), F


def bump_on_plane(diameter: float = 110.0, bump_radius: float = 35.0, height: float = 12.0,
                  rings: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A hat: the disk of ``diameter`` on z = h (1 − r²/a²)³ for r < a, z = 0 beyond (n up).

    The bump is C² where it meets the plane. Its top is umbilic, the plane around it is flat
    (umbilic), and in between k1 turns from circumferential (on the flank) to radial (at the foot)
    through a ring where |κr| = |κθ|: large umbilic regions around anisotropic ones.
    """
    P, F = disk(rings)
    xy = 0.5 * diameter * P
    return np.column_stack([xy, _bump(xy, bump_radius, height)[0]]), F


def cap_cylinder_blend(radius: float = 40.0, cylinder_length: float = 50.0, cap_extent: float = 28.0,
                       half_width: float = 28.0, n_x: int = 40, n_y: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Half a capsule, as a graph (n up): a cylinder of ``radius`` along x for x ≤ 0 (z = √(r² − y²))
    blended C¹ into a sphere cap of the same radius for x > 0 (z = √(r² − x² − y²)).

    The grid spans x ∈ [−cylinder_length, cap_extent], y ∈ [−half_width, half_width]; k1 runs
    around the cylinder (along y); the cap is umbilic.
    """
    if not (cap_extent ** 2 + half_width ** 2 < radius ** 2):
        raise ValueError(f"cap_extent = {cap_extent} and half_width = {half_width} must stay inside "
                         f"the sphere of radius {radius}")
    UV, F = grid(n_x, n_y)
    x = -cylinder_length + (cylinder_length + cap_extent) * UV[:, 0]
    y = half_width * (2.0 * UV[:, 1] - 1.0)
    xy = np.column_stack([x, y])
    return np.column_stack([xy, _blend(xy, radius)[0]]), F


# ---------------------------------------------------------------------------------------------
# exact principal curvatures (the truth the engine is measured against)


@dataclass(frozen=True)
class ExactCurvature:
    """Exact principal curvatures at points of an analytic surface, signed as design-format.md.

    Attributes
    ----------
    kappa1 : (p,) the principal curvature of largest |κ|; kappa2 : (p,) the other one.
    direction1 : (p, 3) unit tangent along kappa1 (a line: its sign is arbitrary).
    normal : (p, 3) unit normal of the winding the generators use.
    """

    kappa1: np.ndarray
    kappa2: np.ndarray
    direction1: np.ndarray
    normal: np.ndarray

    @property
    def anisotropy(self) -> np.ndarray:
        """(p,) (|κ1| − |κ2|) / (|κ1| + |κ2|), 0 where both vanish (a plane)."""
        a, b = np.abs(self.kappa1), np.abs(self.kappa2)
        total = a + b
        return np.where(total > 0, (a - b) / np.where(total > 0, total, 1.0), 0.0)


def _principal(tangents: tuple[np.ndarray, np.ndarray], normal: np.ndarray, first: np.ndarray,
               second: np.ndarray) -> ExactCurvature:
    """Principal curvatures from the fundamental forms in a parametrization.

    tangents : ∂X/∂u, ∂X/∂v (p, 3); normal : (p, 3) unit; first, second : (p, 2, 2) forms I and II
    with II = ⟨∂²X, n⟩. The shape operator is I⁻¹ II; its eigenvalues are the standard curvatures
    (positive where the surface bends toward n), negated for the design format's sign (positive
    where it bulges toward n).
    """
    S = np.linalg.solve(first, second)                         # (p, 2, 2), not symmetric
    tr, det = S[:, 0, 0] + S[:, 1, 1], np.linalg.det(S)
    disc = np.sqrt(np.maximum(0.25 * tr ** 2 - det, 0.0))
    k_a, k_b = 0.5 * tr + disc, 0.5 * tr - disc
    big = np.where(np.abs(k_a) >= np.abs(k_b), k_a, k_b)
    small = np.where(np.abs(k_a) >= np.abs(k_b), k_b, k_a)
    # eigenvector of S for `big`: (S − big I) w = 0; take the better-conditioned row
    r0 = np.column_stack([S[:, 0, 1], big - S[:, 0, 0]])
    r1 = np.column_stack([big - S[:, 1, 1], S[:, 1, 0]])
    w = np.where((np.linalg.norm(r0, axis=1) >= np.linalg.norm(r1, axis=1))[:, None], r0, r1)
    w = np.where(np.linalg.norm(w, axis=1)[:, None] > 0, w, np.array([1.0, 0.0]))
    d = w[:, :1] * tangents[0] + w[:, 1:] * tangents[1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return ExactCurvature(kappa1=-big, kappa2=-small, direction1=d, normal=normal)


def graph_curvature(xy: np.ndarray, gradient: np.ndarray, hessian: np.ndarray) -> ExactCurvature:
    """Exact curvatures of a graph z = f(x, y) with n up, from f's gradient (p, 2) and Hessian (p, 2, 2)."""
    fx, fy = gradient[:, 0], gradient[:, 1]
    W = np.sqrt(1.0 + fx ** 2 + fy ** 2)
    zero, one = np.zeros_like(fx), np.ones_like(fx)
    tu, tv = np.column_stack([one, zero, fx]), np.column_stack([zero, one, fy])
    n = np.column_stack([-fx, -fy, one]) / W[:, None]
    first = np.stack([np.stack([1 + fx ** 2, fx * fy], -1), np.stack([fx * fy, 1 + fy ** 2], -1)], -2)
    return _principal((tu, tv), n, first, hessian / W[:, None, None])


def _bump(xy: np.ndarray, a: float, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f = h (1 − t)³ with t = r²/a² inside r < a, 0 outside; its gradient and Hessian."""
    t = np.minimum((xy ** 2).sum(axis=1) / a ** 2, 1.0)
    inside = t < 1.0
    f = np.where(inside, h * (1 - t) ** 3, 0.0)
    # ∂f/∂x_i = −6h (1 − t)² x_i / a²; ∂²f = 24h (1 − t) x_i x_j / a⁴ − 6h (1 − t)² δ_ij / a²
    g = (-6 * h * (1 - t) ** 2 / a ** 2)[:, None] * xy
    H = ((24 * h * (1 - t) / a ** 4)[:, None, None] * np.einsum("pi,pj->pij", xy, xy)
         - (6 * h * (1 - t) ** 2 / a ** 2)[:, None, None] * np.eye(2))
    return f, np.where(inside[:, None], g, 0.0), np.where(inside[:, None, None], H, 0.0)


def _blend(xy: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f = √(r² − max(x, 0)² − y²); its gradient and Hessian."""
    x = np.maximum(xy[:, 0], 0.0)
    y = xy[:, 1]
    f = np.sqrt(r ** 2 - x ** 2 - y ** 2)
    g = np.column_stack([-x / f, -y / f])
    f3 = f ** 3
    H = np.stack([np.stack([-(r ** 2 - y ** 2) / f3, -x * y / f3], -1),
                  np.stack([-x * y / f3, -(r ** 2 - x ** 2) / f3], -1)], -2)
    H[:, 0, 0] = np.where(xy[:, 0] > 0, H[:, 0, 0], 0.0)
    return f, g, H


def saddle_curvature(xy: np.ndarray, kappa_x: float, kappa_y: float) -> ExactCurvature:
    """Exact curvatures of ``saddle``'s z = (κx x² − κy y²) / 2 at points ``xy`` (p, 2)."""
    g = np.column_stack([kappa_x * xy[:, 0], -kappa_y * xy[:, 1]])
    H = np.broadcast_to(np.diag([kappa_x, -kappa_y]), (len(xy), 2, 2)).copy()
    return graph_curvature(xy, g, H)


def bump_curvature(xy: np.ndarray, bump_radius: float = 35.0, height: float = 12.0) -> ExactCurvature:
    """Exact curvatures of ``bump_on_plane`` at points ``xy`` (p, 2)."""
    _, g, H = _bump(xy, bump_radius, height)
    return graph_curvature(xy, g, H)


def blend_curvature(xy: np.ndarray, radius: float = 40.0) -> ExactCurvature:
    """Exact curvatures of ``cap_cylinder_blend`` at points ``xy`` (p, 2)."""
    _, g, H = _blend(xy, radius)
    return graph_curvature(xy, g, H)


def torus_curvature(points: np.ndarray, R: float = 50.0, r: float = 20.0) -> ExactCurvature:
    """Exact curvatures of ``torus_patch`` at the points of the torus nearest to ``points`` (p, 3):
    1/r along the meridians (the tube), cos v / (R + r cos v) along the parallels, n outward."""
    u = np.arctan2(points[:, 1], points[:, 0])
    v = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]) - R)
    meridian = np.column_stack([-np.sin(v) * np.cos(u), -np.sin(v) * np.sin(u), np.cos(v)])
    n = np.column_stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)])
    return ExactCurvature(kappa1=np.full(len(points), 1.0 / r), kappa2=np.cos(v) / (R + r * np.cos(v)),
                          direction1=meridian, normal=n)


def cylinder_curvature(points: np.ndarray, radius: float = 40.0) -> ExactCurvature:
    """Exact curvatures of ``cylinder_patch`` (axis z, n outward): 1/radius around, 0 along."""
    t = np.arctan2(points[:, 1], points[:, 0])
    around = np.column_stack([-np.sin(t), np.cos(t), np.zeros(len(t))])
    n = np.column_stack([np.cos(t), np.sin(t), np.zeros(len(t))])
    return ExactCurvature(kappa1=np.full(len(points), 1.0 / radius), kappa2=np.zeros(len(points)),
                          direction1=around, normal=n)
