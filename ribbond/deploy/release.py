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
from .compare import kabsch
from .solver import newton

__all__ = ["Sheet", "Path", "NOMINAL", "Release", "release", "curl_kick"]

#: Default number of release steps (the bench saddle's nominal prediction: the same at 20 and 40 steps).
DEFAULT_STEPS = 20
#: Equilibrium: out-of-balance force at most this × the sheet's force scale (``Sheet.force_scale``).
FORCE_TOLERANCE = 1e-6
#: Equilibrium: the last Newton step moved no vertex more than this × the sheet's diagonal.
STEP_TOLERANCE = 1e-5
#: Release fraction of step k of N: (k / N) ** SCHEDULE (small steps first, where the sheet buckles),
#: after a first step to ``ONSET``: the flat sheet's buckling, resolved the same way whatever N.
SCHEDULE = 3.0
ONSET = 1e-4
#: A step that does not reach equilibrium within Newton's cap is halved, at most this many times.
MAX_HALVINGS = 2
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
    steps: int | None = None                     # its own number of steps (None: the caller's)


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


@dataclass(frozen=True)
class _Path:
    """Where the release is: X at fraction t, and X one step (dt) before (None at the start)."""

    X: np.ndarray
    previous: np.ndarray | None
    t: float
    dt: float


def _predictor(state: _Path, dt: float) -> np.ndarray:
    """The secant predictor: the path continued as it went over the last step, its change of shape
    only (the last state registered onto this one first: the pinned vertices may differ between
    steps, and an extrapolated rigid motion would grow from step to step)."""
    if state.previous is None:
        return state.X
    R, t = kabsch(state.previous, state.X)
    before = state.previous @ R.T + t
    return state.X + (state.X - before) * min(dt / state.dt, 4.0)


def _advance(sheet: Sheet, path: Path, state: _Path, t: float, max_iterations: int, scale: float, gtol: float,
             halvings: int = MAX_HALVINGS):
    """Solve the step from ``state`` to fraction t; a step that does not converge is made in two
    halves (up to ``halvings`` deep). Returns (the new state, the last Newton result, iterations)."""
    dt = t - state.t
    E = sheet.energy_at(t, t ** path.curvature_exponent)
    r = newton(E, _predictor(state, dt), max_iterations=max_iterations, step_tolerance=STEP_TOLERANCE,
               scale=scale, gradient_tolerance=gtol)
    if r.converged or halvings == 0:
        return _Path(X=r.X, previous=state.X, t=t, dt=dt), r, r.iterations
    mid, r1, it1 = _advance(sheet, path, state, state.t + 0.5 * dt, max_iterations, scale, gtol, halvings - 1)
    end, r2, it2 = _advance(sheet, path, mid, t, max_iterations, scale, gtol, halvings - 1)
    return end, r2, r.iterations + it1 + it2


def release(sheet: Sheet, *, steps: int = DEFAULT_STEPS, path: Path = NOMINAL, max_iterations: int = 15,
            progress: Callable[[int, int, int], None] | None = None) -> Release:
    """Release the printed sheet along ``path`` in ``steps`` steps (module docstring).

    Parameters
    ----------
    sheet : the printed sheet; steps : release steps (≥ 1).
    path : the path (default the nominal one).
    max_iterations : Newton's cap per step.
    progress : called after each step with (step, steps, Newton iterations so far); the steps are
        the first one to ``ONSET`` and those of the schedule beyond it.

    Returns
    -------
    Release, its X the equilibrium at full release (in the flat sheet's frame, rigid motion pinned).
    """
    if steps < 1:
        raise ValueError(f"steps must be at least 1, got {steps}")
    scale = sheet.diagonal
    gtol = FORCE_TOLERANCE * sheet.force_scale
    X = np.column_stack([sheet.uv, path.kick_sign * curl_kick(sheet)])
    steps = path.steps or steps
    fractions = [ONSET] + [f for f in (np.arange(1, steps + 1) / steps) ** SCHEDULE if f > ONSET]
    state = _Path(X=X, previous=None, t=0.0, dt=0.0)
    iterations, converged, energy, gnorm = 0, True, 0.0, 0.0
    for k, t in enumerate(fractions, start=1):
        state, r, it = _advance(sheet, path, state, t, max_iterations, scale, gtol)
        iterations += it
        converged &= r.converged
        energy, gnorm = r.energy, r.gradient_norm
        if progress is not None:
            progress(k, len(fractions), iterations)
    X = state.X
    return Release(X=X, energy=energy, iterations=iterations, converged=bool(converged), steps=steps,
                   path=path, gradient_norm=gnorm)
