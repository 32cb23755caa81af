"""Principal curvatures and directions per face (§4.3: k1 is the direction of largest |κ|).

Vertex curvatures come from libigl's quadric fit; each face averages the shape operators of its
corners in its isometric frame (``frames.py``).

Sign convention (design-format.md): κ > 0 where the surface bulges toward its normal n, i.e.
the centre of curvature lies on the −n side; a sphere with outward normals has κ = +1/r.
"""

from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np

from .frames import FaceFrames


@dataclass(frozen=True)
class Curvature:
    """Per-face curvature of the target surface.

    Attributes
    ----------
    shape_operator : (m, 2, 2) symmetric second fundamental form in each face's frame.
    kappa1 : (m,) the principal curvature of largest magnitude, signed.
    kappa2 : (m,) the other principal curvature, signed (|kappa2| ≤ |kappa1|).
    angle : (m,) direction of kappa1 in the face frame, radians from e1 (a line: mod π).
    alignment : (m,) complex (|κ1| − |κ2|) e^{2i angle}: the curvature line field in the squared
        representation of a 2-direction field, weighted by how well k1 is defined (0 at umbilics).
    """

    shape_operator: np.ndarray
    kappa1: np.ndarray
    kappa2: np.ndarray
    angle: np.ndarray
    alignment: np.ndarray

    def normal_curvature(self, directions: np.ndarray) -> np.ndarray:
        """κ_n(d) = dᵀ II d for unit directions d (m, 2) in the face frames."""
        return np.einsum("mi,mij,mj->m", directions, self.shape_operator, directions)


def face_curvature(V: np.ndarray, F: np.ndarray, frames: FaceFrames) -> Curvature:
    """Principal curvatures per face, κ1 the one of largest |κ| (§4.3).

    libigl's quadric fit gives the principal curvatures and directions at the vertices (it
    stays accurate at the boundary, where normals averaged from one side are not); the
    shape operators of a face's three corners, projected into its frame, are averaged.

    Parameters
    ----------
    V : (n, 3) vertex positions; F : (m, 3) faces; frames : their isometric frames.
    """
    PD1, PD2, PV1, PV2, bad = igl.principal_curvature(
        np.ascontiguousarray(V, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64))
    weight = np.ones(len(V))
    weight[np.asarray(bad, dtype=np.int64)] = 0.0        # fits that failed: left out
    B = np.stack([frames.e1, frames.e2], axis=2)           # (m, 3, 2): world -> frame
    p1 = np.einsum("mki,mij->mkj", PD1[F], B)              # (m, 3 corners, 2)
    p2 = np.einsum("mki,mij->mkj", PD2[F], B)
    w = weight[F]                                          # (m, 3)
    II = (np.einsum("mk,mki,mkj->mij", w * PV1[F], p1, p1)
          + np.einsum("mk,mki,mkj->mij", w * PV2[F], p2, p2))
    II /= np.maximum(w.sum(axis=1), 1.0)[:, None, None]
    a, b, c = II[:, 0, 0], 0.5 * (II[:, 0, 1] + II[:, 1, 0]), II[:, 1, 1]
    II = np.stack([np.stack([a, b], -1), np.stack([b, c], -1)], -2)
    mean, half = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    k_max, k_min = mean + half, mean - half
    phi_max = 0.5 * np.arctan2(2 * b, a - c)                 # direction of k_max
    max_wins = np.abs(k_max) >= np.abs(k_min)
    kappa1 = np.where(max_wins, k_max, k_min)
    kappa2 = np.where(max_wins, k_min, k_max)
    angle = np.where(max_wins, phi_max, phi_max + 0.5 * np.pi)
    # (|k_max| − |k_min|) e^{2i phi_max} turns by π (a quarter turn of the line) when k_min wins.
    alignment = (np.abs(k_max) - np.abs(k_min)) * np.exp(2j * phi_max)
    return Curvature(shape_operator=II, kappa1=kappa1, kappa2=kappa2,
                     angle=np.mod(angle, np.pi), alignment=alignment)
