"""What the refinement tests (``test_refine``, ``test_refine_smooth``) share: coarse analytic surfaces,
each with its distance to the analytic surface and, where k1 is defined, its exact curvature; the
topology and boundary check; the curvature errors of a refined mesh."""

from __future__ import annotations

from collections.abc import Callable

import igl
import numpy as np

from ribbond.design import surfaces as S
from ribbond.design.curvature import face_curvature
from ribbond.design.frames import face_frames

Mesh = tuple[np.ndarray, np.ndarray]


def _sphere_distance(P: np.ndarray) -> np.ndarray:
    return np.abs(np.linalg.norm(P, axis=1) - 60.0)


def _saddle_distance(P: np.ndarray) -> np.ndarray:
    return np.abs(P[:, 2] - 0.5 * (P[:, 0] ** 2 / 30 - P[:, 1] ** 2 / 60))


def _cylinder_distance(P: np.ndarray) -> np.ndarray:
    return np.abs(np.hypot(P[:, 0], P[:, 1]) - 40.0)


def _torus_distance(P: np.ndarray) -> np.ndarray:
    return np.abs(np.hypot(np.hypot(P[:, 0], P[:, 1]) - 50.0, P[:, 2]) - 20.0)


# (name, coarse mesh, distance to the analytic surface, exact curvature at points)
CASES: list[tuple[str, Mesh, Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], S.ExactCurvature] | None]] = [
    ("sphere cap", S.sphere_cap(60.0, 40.0, rings=8), _sphere_distance, None),
    ("saddle", S.saddle(100.0, 1 / 30, 1 / 60, rings=12), _saddle_distance,
     lambda P: S.saddle_curvature(P[:, :2], 1 / 30, 1 / 60)),
    ("cylinder", S.cylinder_patch(40.0, 120.0, 60.0, 20, 10), _cylinder_distance,
     lambda P: S.cylinder_curvature(P, 40.0)),
    ("torus patch", S.torus_patch(50.0, 20.0, (0, 60), (-30, 30), 30, 15), _torus_distance,
     lambda P: S.torus_curvature(P, 50.0, 20.0)),
]
IDS = [c[0] for c in CASES]


def curvature_errors(V: np.ndarray, F: np.ndarray, exact: Callable[[np.ndarray], S.ExactCurvature]
                     ) -> tuple[float, float]:
    """Of the engine's per-face curvature on (V, F): median |κ1 − exact| / max |κ1|, and the median
    angle (°) of its k1 off the exact one on the anisotropic faces."""
    fr = face_frames(V, F)
    c = face_curvature(V, F, fr)
    E = exact(V[F].mean(axis=1))
    d = np.cos(c.angle)[:, None] * fr.e1 + np.sin(c.angle)[:, None] * fr.e2
    t = E.direction1 - np.einsum("ij,ij->i", E.direction1, fr.n)[:, None] * fr.n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", d, t)), 0, 1)))[E.anisotropy > 0.3]
    return float(np.median(np.abs(c.kappa1 - E.kappa1)) / np.abs(E.kappa1).max()), float(np.median(angle))


def assert_topology_and_boundary_order(V: np.ndarray, F: np.ndarray, refined_V: np.ndarray, refined_F: np.ndarray,
                                       levels: int) -> None:
    """A refinement of (V, F) by ``levels`` rounds keeps a disk, 4^levels faces per face, and the coarse
    boundary vertices (the first refined ones) in the same cyclic order (either direction), evenly
    spaced with 2^levels − 1 new ones between neighbours."""
    assert len(refined_F) == 4 ** levels * len(F)
    edges = igl.edges(refined_F)
    assert len(refined_V) - len(edges) + len(refined_F) == 1        # still a disk (Euler characteristic 1)
    loops = igl.boundary_loop_all(refined_F)
    assert len(loops) == 1
    loop = np.asarray(loops[0])
    old = np.flatnonzero(loop < len(V))
    coarse = np.asarray(igl.boundary_loop(F))
    kept = loop[old]
    start = int(np.flatnonzero(coarse == kept[0])[0])
    rolled = np.roll(coarse, -start)
    assert np.array_equal(kept, rolled) or np.array_equal(kept, np.roll(rolled[::-1], 1))
    assert np.all(np.diff(old) == 2 ** levels) and len(loop) == 2 ** levels * len(coarse)
