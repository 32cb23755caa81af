"""The predicted surface against the target: rigid registration and deviation (Table 1's "Dev.").

The prediction and the target share their vertices (the prediction's vertices are points of the
flat surface, whose target positions are known through the flat map), so the registration is the
least-squares rigid motion between corresponding points (Kabsch 1976). The deviation is then, as
in §8 of the paper, the distance of each predicted vertex to its closest point on the target
surface, as a percentage of the target's bounding-box diagonal: mean, 99th percentile and maximum.
"""

from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np

__all__ = ["kabsch", "Deviation", "surface_deviation", "registered_deviation"]


def kabsch(P: np.ndarray, Q: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The rotation R (3, 3) and translation t (3,) minimizing Σ w_i |R p_i + t − q_i|².

    Parameters
    ----------
    P, Q : (n, 3) corresponding points (n ≥ 3, not all on a line); weights : (n,) ≥ 0 or None.

    Returns
    -------
    R (det +1) and t, so that ``P @ R.T + t`` is P registered onto Q.
    """
    P = np.asarray(P, dtype=float)
    Q = np.asarray(Q, dtype=float)
    if P.shape != Q.shape or P.ndim != 2 or P.shape[1] != 3 or len(P) < 3:
        raise ValueError(f"kabsch needs two (n, 3) arrays of one shape with n ≥ 3, got {P.shape} and {Q.shape}")
    w = np.ones(len(P)) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (len(P),) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be (n,) non-negative with a positive sum")
    w = w / w.sum()
    pc, qc = w @ P, w @ Q
    Hm = (P - pc).T @ (w[:, None] * (Q - qc))
    U, _, Vt = np.linalg.svd(Hm)
    dfix = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, dfix]) @ U.T
    return R, qc - R @ pc


@dataclass(frozen=True)
class Deviation:
    """Distances of the registered prediction to the target.

    Attributes
    ----------
    V : (k, 3) the prediction registered onto the target; distance : (k,) mm per vertex;
    diagonal : the target's bounding-box diagonal, mm; mean_pct, p99_pct, max_pct : % of it.
    """

    V: np.ndarray
    distance: np.ndarray
    diagonal: float
    mean_pct: float
    p99_pct: float
    max_pct: float

    def as_dict(self) -> dict[str, float]:
        """{"mean", "p99", "max"} in % of the diagonal (design.json's ``deviation_pct``)."""
        return {"mean": self.mean_pct, "p99": self.p99_pct, "max": self.max_pct}


def surface_deviation(X: np.ndarray, X_target: np.ndarray, target_V: np.ndarray, target_F: np.ndarray
                      ) -> Deviation:
    """Register X onto its corresponding target points and measure it against the target surface.

    Parameters
    ----------
    X : (k, 3) predicted vertices; X_target : (k, 3) the same vertices on the target (correspondence);
    target_V : (n, 3), target_F : (m, 3) the target surface (distances are to it).
    """
    R, t = kabsch(X, X_target)
    return registered_deviation(X @ R.T + t, target_V, target_F)


def registered_deviation(Y: np.ndarray, target_V: np.ndarray, target_F: np.ndarray) -> Deviation:
    """Measure a surface already registered onto the target (``deployed.obj``) against it.

    Parameters
    ----------
    Y : (k, 3) the registered vertices, mm; target_V : (n, 3), target_F : (m, 3) the target surface.

    Returns
    -------
    The distance of each vertex of Y to its closest point on the target surface (k,) and its figures.
    """
    Y = np.ascontiguousarray(Y, dtype=np.float64)
    if Y.ndim != 2 or Y.shape[1] != 3 or not len(Y):
        raise ValueError(f"the registered surface must be (k, 3) vertices with k ≥ 1, got {Y.shape}")
    if not np.all(np.isfinite(Y)):
        raise ValueError("the registered surface has a vertex that is not finite")
    TV = np.ascontiguousarray(target_V, dtype=np.float64)
    TF = np.ascontiguousarray(target_F, dtype=np.int64)
    d2, _, _ = igl.point_mesh_squared_distance(np.ascontiguousarray(Y), TV, TF)
    dist = np.sqrt(np.maximum(np.asarray(d2), 0.0))
    diag = float(np.linalg.norm(TV.max(axis=0) - TV.min(axis=0)))
    if not diag > 0:
        raise ValueError("the target has a zero bounding box")
    pct = 100.0 * dist / diag
    return Deviation(V=Y, distance=dist, diagonal=diag, mean_pct=float(pct.mean()),
                     p99_pct=float(np.percentile(pct, 99)), max_pct=float(pct.max()))
