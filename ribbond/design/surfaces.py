"""Parametric target surfaces built from scratch: the test, example and benchmark meshes.

Every function returns ``(V, F)``: ``V`` (n, 3) float64 vertex positions in mm and ``F`` (m, 3)
int64 faces, a consistently oriented topological disk. The winding gives the normal n stated in
each docstring, because the sign of κ1 (front or back) follows from it.
"""

from __future__ import annotations

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
