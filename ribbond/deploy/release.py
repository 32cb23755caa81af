"""The release of the printed sheet along its physical path (issue 23).

The sheet is printed flat: the fabric held at its pre-stretch, the ribbons flat on it. That state is
at rest (ā = I in the flat coordinates, b̄ = 0) and is where every prediction starts. Released, the
fabric contracts toward its relaxed metric and the ribbons curl: the rest forms go from the printed
state to the released ones (``rest_forms``). ``release`` ramps them in ``steps`` steps,

    ā(t) = (1 − t) I + t Ā,        b̄(t) = r(t) B̄,

t = k / steps, r(t) = t (the nominal path) or a plausible variant (the curvature leading or lagging
the contraction, ``Path``), and solves each step to equilibrium from the last (``solver.newton``,
stopped by the out-of-balance force and the step, never by how fast the energy creeps). Nothing here
reads a target: the start is the flat sheet, and its symmetry (a flat sheet curls up or down
equally well) is broken by the physics, the side each ribbon bends toward: the first step starts
from the flat sheet lifted by the small height field that the layout's rest curvature B̄ gives a
plate held flat by its own contraction (``curl_kick``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .shell import ShellEnergy, edge_basis_forms
from .solver import newton

__all__ = ["Sheet", "Path", "NOMINAL", "Release", "release", "curl_kick"]

#: Default number of release steps (the nominal prediction agrees with 40 steps within 0.3 % of the diagonal).
DEFAULT_STEPS = 10
#: Equilibrium: out-of-balance force at most this × the sheet's force scale (``Sheet.force_scale``).
FORCE_TOLERANCE = 1e-7
#: Equilibrium: the last Newton step moved no vertex more than this × the sheet's diagonal.
STEP_TOLERANCE = 1e-6
#: Height of the symmetry-breaking lift, × the flat sheet's diagonal.
KICK = 1e-3


@dataclass(frozen=True)
class Sheet:
    """The printed sheet: its flat mesh, its rest forms when fully released, its stiffness.

    Attributes
    ----------
    uv : (n, 2) the flat (printed, pre-stretched) positions, mm; F : (m, 3) faces, counter-clockwise.
    abar, bbar : (m, 2, 2) released rest forms Ā, B̄ in flat Cartesian coordinates.
    stretch : (m,) membrane stiffness D_s, N/mm; bend : (m,) bending stiffness D_b, N·mm.
    nu : Poisson's ratio.
    """

    uv: np.ndarray
    F: np.ndarray
    abar: np.ndarray
    bbar: np.ndarray
    stretch: np.ndarray
    bend: np.ndarray
    nu: float

    @property
    def diagonal(self) -> float:
        """The flat sheet's bounding-box diagonal, mm (the scale of every tolerance: not the target's)."""
        return float(np.linalg.norm(self.uv.max(axis=0) - self.uv.min(axis=0)))

    @property
    def force_scale(self) -> float:
        """N: the force a unit strain of the median membrane puts on an edge of median length."""
        e = np.linalg.norm(self.uv[self.F[:, 1]] - self.uv[self.F[:, 0]], axis=1)
        return float(np.median(self.stretch) * np.median(e))

    def energy_at(self, t: float, r: float | None = None) -> ShellEnergy:
        """The shell energy with the rest forms at release fraction t (metric) and r (curvature, default t)."""
        r = t if r is None else r
        abar = (1.0 - t) * np.eye(2)[None] + t * self.abar
        bbar = r * self.bbar
        a = edge_basis_forms(self.uv, self.F, abar)
        b = edge_basis_forms(self.uv, self.F, bbar)
        area = 0.5 * np.sqrt(np.maximum(a[:, 0] * a[:, 2] - a[:, 1] ** 2, 0.0))
        nu = self.nu
        return ShellEnergy(self.F, a, b, area * self.stretch / (8 * (1 - nu ** 2)),
                           area * self.bend / (2 * (1 - nu ** 2)), nu)


@dataclass(frozen=True)
class Path:
    """A release path: the curvature's fraction r = t^exponent while the metric's is t, and the
    sign of the symmetry-breaking lift (+1: the side the ribbons bend toward; −1: against it)."""

    name: str = "nominal"
    curvature_exponent: float = 1.0
    kick_sign: float = 1.0


NOMINAL = Path()


@dataclass(frozen=True)
class Release:
    """The released sheet.

    Attributes
    ----------
    X : (n, 3) the equilibrium at full release; energy : its energy, N·mm; iterations : Newton
    iterations over all steps; converged : every step reached equilibrium; steps : release steps;
    path : the path followed; gradient_norm : the last out-of-balance force, N.
    """

    X: np.ndarray
    energy: float
    iterations: int
    converged: bool
    steps: int
    path: Path
    gradient_norm: float


def curl_kick(sheet: Sheet) -> np.ndarray:
    """(n,) the height field of the sheet's own curl: the plate w minimizing Σ_f A_f D_b |∇²w − B̄|²
    (its Hessian fitted to the rest curvature in the least-squares sense), scaled to ``KICK`` ×
    the diagonal. Where the ribbons bend toward +z the sheet lifts toward +z: the physical side.

    Discretized by per-face linear gradients averaged to vertices (a second difference of the P1
    field): one sparse least-squares solve.
    """
    uv, F = sheet.uv, sheet.F
    n, m = len(uv), len(F)
    G = _face_gradient(uv, F)                                        # (2m, n): ∇w per face
    area = _areas(uv, F)
    lump = sp.csr_matrix((np.repeat(area, 3), (F.ravel(), np.repeat(np.arange(m), 3))), shape=(n, m))
    avg = sp.diags(1.0 / np.maximum(np.asarray(lump.sum(axis=1)).ravel(), 1e-300)) @ lump   # (n, m)
    gx, gy = G[:m], G[m:]
    vx, vy = avg @ gx, avg @ gy                                      # vertex gradients (n, n)
    H = [G[:m] @ vx, G[m:] @ vx, G[m:] @ vy]                         # w_xx, w_xy (= w_yx), w_yy per face
    wgt = np.sqrt(area * np.maximum(sheet.bend, 1e-30))
    W = sp.diags(wgt)
    A = sp.vstack([W @ H[0], np.sqrt(2.0) * (W @ H[1]), W @ H[2]]).tocsr()
    # the shell's b is −∇²w for a height field w over the sheet (b > 0 bulges toward +z)
    b = -np.concatenate([wgt * sheet.bbar[:, 0, 0], np.sqrt(2.0) * wgt * sheet.bbar[:, 0, 1],
                         wgt * sheet.bbar[:, 1, 1]])
    if not np.any(b):
        return np.zeros(n)
    # affine w has no curvature: fix it by a small Tikhonov term (the null space is 3-dimensional)
    reg = 1e-8 * float(A.multiply(A).sum()) / n
    w = spla.spsolve((A.T @ A + reg * sp.eye(n)).tocsc(), A.T @ b)
    P = np.column_stack([np.ones(n), uv])
    w -= P @ np.linalg.lstsq(P, w, rcond=None)[0]                  # remove the plane
    peak = float(np.abs(w).max())
    return w * (KICK * sheet.diagonal / peak) if peak > 0 else w


def _areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _face_gradient(uv: np.ndarray, F: np.ndarray) -> sp.csr_matrix:
    """(2m, n): rows 0..m−1 the x-, m..2m−1 the y-derivative of a P1 field on each face."""
    m = len(F)
    p0, p1, p2 = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    det = (p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1]) - (p2[:, 0] - p0[:, 0]) * (p1[:, 1] - p0[:, 1])
    # gradient of the hat function of vertex i: perpendicular of the opposite edge / (2A)
    opp = np.stack([p2 - p1, p0 - p2, p1 - p0], axis=1)             # (m, 3, 2)
    gx = -opp[:, :, 1] / det[:, None]
    gy = opp[:, :, 0] / det[:, None]
    rows = np.concatenate([np.repeat(np.arange(m), 3), m + np.repeat(np.arange(m), 3)])
    cols = np.concatenate([F.ravel(), F.ravel()])
    return sp.csr_matrix((np.concatenate([gx.ravel(), gy.ravel()]), (rows, cols)), shape=(2 * m, len(uv)))


def release(sheet: Sheet, *, steps: int = DEFAULT_STEPS, path: Path = NOMINAL, max_iterations: int = 60,
            progress: Callable[[int, int, int], None] | None = None) -> Release:
    """Release the printed sheet along ``path`` in ``steps`` steps (module docstring).

    Parameters
    ----------
    sheet : the printed sheet; steps : release steps (≥ 1).
    path : the path (default the nominal one).
    max_iterations : Newton's cap per step.
    progress : called after each step with (step, steps, Newton iterations so far).

    Returns
    -------
    Release, its X the equilibrium at full release (in the flat sheet's frame, rigid motion pinned).
    """
    if steps < 1:
        raise ValueError(f"steps must be at least 1, got {steps}")
    scale = sheet.diagonal
    gtol = FORCE_TOLERANCE * sheet.force_scale
    X = np.column_stack([sheet.uv, path.kick_sign * curl_kick(sheet)])
    iterations, converged, energy, gnorm = 0, True, 0.0, 0.0
    for k in range(1, steps + 1):
        t = k / steps
        E = sheet.energy_at(t, t ** path.curvature_exponent)
        r = newton(E, X, max_iterations=max_iterations, step_tolerance=STEP_TOLERANCE, scale=scale,
                   gradient_tolerance=gtol)
        X, energy, gnorm = r.X, r.energy, r.gradient_norm
        iterations += r.iterations
        converged &= r.converged
        if progress is not None:
            progress(k, steps, iterations)
    return Release(X=X, energy=energy, iterations=iterations, converged=bool(converged), steps=steps,
                   path=path, gradient_norm=gnorm)
