"""The layout optimized against the prediction (issue 34, the rest of issue 24).

The forward design gives each ribbon the thickness τ_r whose curvature κ(τ_r, μ2) (the curvature
table) is the target's κ1 where it sits. The prediction of that layout (``predict``) deviates from
the target: the homogenized sheet's equilibrium is not the sum of its rest curvatures. Here the
thicknesses are changed so that the predicted shape comes closer:

    min_τ  J(X(τ)),   ∇_X E(X, τ) = 0,   τ_min ≤ τ_r ≤ τ_max (the table's range: printable),

X the equilibrium of the released sheet (``release.Sheet.energy_at(1)``), J the mean squared
distance of each vertex to its own point of the target after the registration (Kabsch), over the
target's diagonal squared (so √J is an RMS fraction of the diagonal; the registration is the best
one, so its own derivative drops out). A vertex matched to its own target point, not to the nearest
one, asks for the intrinsic shape too: ∫K and the area follow it.

τ enters the sheet per face through the coverage's ribbon weights W (``Coverage.ribbon_weights``):
the rest curvature κ_f = Σ_r W_fr ± κ(τ_r, μ2_f) (B̄ = κ_f c_d² d dᵀ) and the mean thickness
τ_f = Σ_r W_fr τ_r of the stiffnesses D_s, D_b. The gradient is the adjoint's: H λ = ∂J/∂X on the
free degrees of freedom (the exact Hessian at the equilibrium, CHOLMOD), dJ/dτ = −λᵀ ∂∇E/∂τ with
``ShellEnergy.rest_sensitivities`` and the chain above. The steps are L-BFGS-B's (box constraints),
each evaluation a Newton solve warm-started from the last equilibrium, within a time budget and an
evaluation cap (deterministic: no randomness, no threads in the order of operations).

The optimization runs on a uniform remesh of the flat domain (``faces``, default 1,200) and reads
the target: it is a design step. Its result is a layout; what that layout deploys to is predicted
afterwards from the flat sheet as printed, like any other (``predict.predict_deployed``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize

from ribbond.design.format import Ribbon
from ribbond.design.thickness import CurvatureTable, table_curvature

from .compare import kabsch
from .predict import Material, Prediction, interpolate, reference_mesh, sheet_for_layout
from .release import FORCE_TOLERANCE, STEP_TOLERANCE, Sheet
from .rest_forms import Coverage, contraction
from .shell import edge_basis_forms
from .solver import _Factor, _SHIFTS, newton, pinned_dofs

__all__ = ["LayoutModel", "layout_model", "Objective", "Optimization", "optimize_layout",
           "DEFAULT_BUDGET_S", "DEFAULT_FACES"]

#: Wall-time budget of the optimization, s (``SolverSettings.optimize_budget_s``).
DEFAULT_BUDGET_S = 40.0
#: Faces of the mesh the optimization solves on.
DEFAULT_FACES = 1200
#: Cap on the objective's evaluations (each a warm-started Newton solve and an adjoint solve).
MAX_EVALUATIONS = 200
#: Newton's cap per evaluation (warm-started: a few iterations suffice).
NEWTON_ITERATIONS = 25
#: What is varied (``report.optimization.variables``).
VARIABLES = ("thickness",)


def table_slope(table: CurvatureTable, side: str, thickness: np.ndarray, mu2: np.ndarray) -> np.ndarray:
    """∂κ/∂τ (k,) of the table's bilinear interpolation (``table_curvature``) at τ, μ2 (k,): the
    slope of the cell τ lies in (the cell to the right at a node), 0 outside the τ range."""
    grid = table.grid(side)
    tt = np.asarray(table.thickness, dtype=float)
    ss = np.asarray(table.spacing, dtype=float)
    i = np.clip(np.searchsorted(tt, thickness, side="right") - 1, 0, len(tt) - 2)
    mu = np.clip(mu2, ss[0], ss[-1])
    j = np.clip(np.searchsorted(ss, mu, side="right") - 1, 0, len(ss) - 2)
    v = np.clip((mu - ss[j]) / (ss[j + 1] - ss[j]), 0.0, 1.0)
    slope = ((1 - v) * (grid[i + 1, j] - grid[i, j]) + v * (grid[i + 1, j + 1] - grid[i, j + 1])) / (tt[i + 1] - tt[i])
    inside = (thickness >= tt[0]) & (thickness <= tt[-1])
    return np.where(inside, slope, 0.0)


@dataclass(frozen=True)
class LayoutModel:
    """The map from the ribbons' thicknesses τ (R,) to the printed sheet on one mesh.

    Attributes
    ----------
    uv : (k, 2), F : (t, 3) the mesh; target : (k, 3) its vertices' target points (registration only).
    base : the sheet of the forward layout (its Ā, area fractions and directions do not depend on τ).
    rows, cols : (q,) the nonzeros of W (face, ribbon); share : (q,) their weights; sign : (q,) ±1 (side).
    mu2 : (q,) the face's measured μ2 (clamped to the table); side_front : (q,) bool.
    shape_cart : (t, 2, 2) c_d² d dᵀ (B̄ = κ_f × it); shape_bbar : (t, 3) the same in the edge basis.
    phi : (t,) plastic area fraction; ribbons : R; table, material : the curvature table and the material.
    """

    uv: np.ndarray
    F: np.ndarray
    target: np.ndarray
    base: Sheet
    rows: np.ndarray
    cols: np.ndarray
    share: np.ndarray
    side_front: np.ndarray
    mu2: np.ndarray
    shape_cart: np.ndarray
    shape_bbar: np.ndarray
    phi: np.ndarray
    ribbons: int
    table: CurvatureTable
    material: Material

    def face_values(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix, sp.csr_matrix]:
        """κ_f (t,), τ_f (t,) and their Jacobians ∂κ_f/∂τ_r, ∂τ_f/∂τ_r (t, R) sparse."""
        t, R = len(self.F), self.ribbons
        tr = tau[self.cols]
        kf = table_curvature(self.table, "front", tr, self.mu2)
        kb = table_curvature(self.table, "back", tr, self.mu2)
        sf = table_slope(self.table, "front", tr, self.mu2)
        sb = table_slope(self.table, "back", tr, self.mu2)
        kap = np.where(self.side_front, kf, -kb)
        dkap = np.where(self.side_front, sf, -sb)
        kappa_f = np.bincount(self.rows, weights=self.share * kap, minlength=t)
        tau_f = np.bincount(self.rows, weights=self.share * tr, minlength=t)
        Dk = sp.csr_matrix((self.share * dkap, (self.rows, self.cols)), shape=(t, R))
        Dt = sp.csr_matrix((self.share, (self.rows, self.cols)), shape=(t, R))
        return kappa_f, tau_f, Dk, Dt

    def sheet(self, tau: np.ndarray) -> tuple[Sheet, tuple]:
        """The printed sheet of thicknesses τ (R,), and what its gradient needs."""
        kappa_f, tau_f, Dk, Dt = self.face_values(tau)
        Ds, Db = self.material.stiffness(self.phi, tau_f)
        bbar_cart = kappa_f[:, None, None] * self.shape_cart
        sheet = Sheet(uv=self.uv, F=self.F, abar=self.base.abar, bbar=bbar_cart, stretch=Ds, bend=Db,
                      nu=self.material.poisson)
        return sheet, (kappa_f, tau_f, Dk, Dt, Ds, Db)

    def gradient(self, d_bbar: np.ndarray, d_stretch: np.ndarray, d_bend: np.ndarray, parts: tuple,
                 stretch_coef: np.ndarray, bend_coef: np.ndarray) -> np.ndarray:
        """d(λᵀ∇E)/dτ (R,) from its derivatives per face (``ShellEnergy.rest_sensitivities``)."""
        _, tau_f, Dk, Dt, Ds, Db = parts
        m = self.material
        dDs = self.phi * m.plastic_young
        dDb = self.phi * m.plastic_young * tau_f ** 2 / 4.0
        per_kappa = (d_bbar * self.shape_bbar).sum(axis=1)
        per_tau = d_stretch * stretch_coef * dDs / Ds + d_bend * bend_coef * dDb / Db
        return Dk.T @ per_kappa + Dt.T @ per_tau


def layout_model(uv: np.ndarray, F: np.ndarray, target: np.ndarray, ribbons: Sequence[Ribbon], *,
                 prestretch: float, ribbon_width: float, table: CurvatureTable,
                 material: Material | None = None) -> LayoutModel:
    """The ``LayoutModel`` of the ribbons on the mesh (uv (k, 2), F (t, 3), target (k, 3))."""
    material = material or Material()
    base, cov = sheet_for_layout(uv, F, ribbons, prestretch=prestretch, ribbon_width=ribbon_width,
                                 table=table, material=material)
    W = cov.ribbon_weights.tocoo()
    sign = np.array([r.side == "front" for r in ribbons], dtype=bool)
    ss = np.asarray(table.spacing, dtype=float)
    mu2 = np.clip(np.where(np.isfinite(cov.mu2), cov.mu2, ss[-1]), ss[0], ss[-1])
    cd = contraction(cov.f_along, prestretch)
    d = cov.direction
    shape_cart = (cd ** 2)[:, None, None] * d[:, :, None] * d[:, None, :]
    return LayoutModel(uv=uv, F=F, target=target, base=base, rows=W.row.astype(np.int64),
                        cols=W.col.astype(np.int64), share=W.data, side_front=sign[W.col], mu2=mu2[W.row],
                        shape_cart=shape_cart, shape_bbar=edge_basis_forms(uv, F, shape_cart), phi=cov.area_fraction,
                        ribbons=len(ribbons), table=table, material=material)


def registered_distance(X: np.ndarray, target: np.ndarray, diagonal: float) -> tuple[float, np.ndarray]:
    """J = mean_i |R x_i + t − q_i|² / diagonal² after the best registration (R, t) of X (k, 3) onto
    the target points (k, 3), and ∂J/∂X (k, 3) (the registration's own derivative vanishes: optimal)."""
    R, t = kabsch(X, target)
    r = X @ R.T + t - target
    scale = 1.0 / (len(X) * diagonal ** 2)
    return float(scale * (r * r).sum()), 2.0 * scale * (r @ R)


class _Budget(Exception):
    """The time budget or the evaluation cap is spent (raised inside L-BFGS-B's objective)."""


class Objective:
    """J(τ) and dJ/dτ by the adjoint, each evaluation warm-started from the last equilibrium.

    Parameters
    ----------
    model : the layout model; X0 : (k, 3) an equilibrium of the forward layout on its mesh.
    """

    def __init__(self, model: LayoutModel, X0: np.ndarray) -> None:
        self.model = model
        self.X = np.asarray(X0, dtype=float)
        self.diagonal = float(np.linalg.norm(model.target.max(axis=0) - model.target.min(axis=0)))
        self.evaluations = 0
        self.newton_iterations = 0
        self._last: tuple[np.ndarray, float, np.ndarray] | None = None

    def equilibrium(self, tau: np.ndarray) -> tuple[np.ndarray, object, tuple]:
        """The equilibrium at full release of thicknesses τ from the last one: X, its energy, the parts."""
        sheet, parts = self.model.sheet(tau)
        E = sheet.energy_at(1.0)
        r = newton(E, self.X, max_iterations=NEWTON_ITERATIONS, step_tolerance=0.1 * STEP_TOLERANCE,
                   scale=sheet.diagonal, gradient_tolerance=0.1 * FORCE_TOLERANCE * sheet.force_scale)
        self.newton_iterations += r.iterations
        return r.X, E, parts

    def __call__(self, tau: np.ndarray) -> tuple[float, np.ndarray]:
        """(J, dJ/dτ (R,)); the equilibrium found becomes the next evaluation's start."""
        tau = np.asarray(tau, dtype=float)
        if self._last is not None and np.array_equal(self._last[0], tau):
            return self._last[1], self._last[2].copy()        # L-BFGS-B starts where the caller did
        X, E, parts = self.equilibrium(tau)
        self.X = X
        self.evaluations += 1
        J, dJ = registered_distance(X, self.model.target, self.diagonal)
        lam = _adjoint(E, X, dJ.ravel())
        d_bbar, d_stretch, d_bend = E.rest_sensitivities(X, lam)
        grad = -self.model.gradient(d_bbar, d_stretch, d_bend, parts, E.stretch_coef, E._bend_coef)
        self._last = (tau.copy(), J, grad.copy())
        return J, grad


def _adjoint(E, X: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """λ (3n,) with H λ = rhs on the free degrees of freedom (the rigid motions pinned as the solver
    pins them, λ = 0 there), H the exact Hessian at X, shifted as little as makes it factorize."""
    pinned = pinned_dofs(X)
    free = np.setdiff1d(np.arange(X.size), pinned)
    _, exact, psd = E.gradient_and_hessians(X, free=free, lower=True)
    H = exact()
    factor = _Factor(H)
    diag = np.flatnonzero(H.indices == np.repeat(np.arange(H.shape[1]), np.diff(H.indptr)))
    mean = float(np.abs(H.data[diag]).mean())
    for shift in _SHIFTS:
        Hs = H.copy()
        Hs.data[diag] += shift * mean
        if factor.factor(Hs):
            break
    else:
        H = psd()
        if not factor.factor(H):
            raise ValueError("the adjoint's Hessian does not factorize at the equilibrium")
    lam = np.zeros(X.size)
    lam[free] = factor.solve(rhs[free])
    return lam


@dataclass(frozen=True)
class Optimization:
    """The optimized layout.

    Attributes
    ----------
    ribbons : the ribbons with their optimized thicknesses (everything else as given).
    thickness : (R,) the optimized τ; forward_thickness : (R,) the given τ (clipped to the table's range).
    objective_forward, objective : J of the given and of the optimized τ (mean squared registered
        distance / diagonal², on the optimization's mesh, from the same start).
    iterations : L-BFGS-B iterations; evaluations : objective evaluations; newton_iterations : theirs.
    stopped : why it stopped ("converged", "time budget", "evaluation cap", "no ribbons").
    time_s : wall time, s; faces : the optimization mesh's faces.
    """

    ribbons: list[Ribbon]
    thickness: np.ndarray
    forward_thickness: np.ndarray
    objective_forward: float
    objective: float
    iterations: int
    evaluations: int
    newton_iterations: int
    stopped: str
    time_s: float
    faces: int

    @staticmethod
    def shape(p: Prediction) -> dict:
        """A prediction as ``report.optimization`` gives it: the deviation and ∫K against the target's."""
        a = p.agreement
        return {"deviation_pct": dict(p.deviation_pct),
                "total_gaussian_curvature": {"predicted": a.curvature_predicted, "target": a.curvature_target}}

    def report(self, forward: Prediction, optimized: Prediction) -> dict:
        """``report.optimization`` of design.json: the forward and the optimized layouts' predictions."""
        shape = self.shape
        return {"forward": shape(forward), "optimized": shape(optimized), "variables": list(VARIABLES),
                "iterations": self.iterations, "time_s": self.time_s}


def _bounded(fun: Objective, t0: float, budget_s: float, max_evaluations: int,
             best: dict) -> Callable[[np.ndarray], tuple[float, np.ndarray]]:
    """The objective for L-BFGS-B in units of %² (J × 10⁴, so that its tolerances are meaningful),
    keeping the best point seen, and stopping (``_Budget``) past the budget or the cap."""
    def f(tau: np.ndarray) -> tuple[float, np.ndarray]:
        if fun.evaluations >= max_evaluations or time.perf_counter() - t0 > budget_s:
            raise _Budget("evaluation cap" if fun.evaluations >= max_evaluations else "time budget")
        J, g = fun(tau)
        if J < best["J"]:
            best.update(J=J, tau=np.array(tau, dtype=float))
        return 1e4 * J, 1e4 * g
    return f


def optimize_layout(flat_uv: np.ndarray, target_V: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon],
                    forward: Prediction, *, prestretch: float, ribbon_width: float, table: CurvatureTable,
                    faces: int = DEFAULT_FACES, budget_s: float = DEFAULT_BUDGET_S,
                    max_evaluations: int = MAX_EVALUATIONS, material: Material | None = None,
                    progress: Callable[[float, str], None] | None = None) -> Optimization:
    """Optimize the ribbons' thicknesses against the predicted shape (module docstring).

    Parameters
    ----------
    flat_uv : (n, 2), target_V : (n, 3), F : (m, 3) the flat surface and the target (as for
        ``predict_deployed``); ribbons : the forward layout.
    forward : the forward layout's prediction (its nominal release starts the optimization).
    prestretch, ribbon_width, table, material : as for ``predict_deployed``.
    faces : the optimization mesh's size; budget_s : wall-time budget, s (> 0);
    max_evaluations : cap on the objective's evaluations (≥ 1).
    progress : called with (fraction of the budget spent, what is being done).

    Returns
    -------
    Optimization (the best τ evaluated: never worse than the forward one on its own objective).
    """
    t0 = time.perf_counter()
    if not budget_s > 0:
        raise ValueError(f"budget_s must be > 0, got {budget_s!r}")
    if max_evaluations < 1:
        raise ValueError(f"max_evaluations must be at least 1, got {max_evaluations}")
    tt = np.asarray(table.thickness, dtype=float)
    tau0 = np.clip(np.array([r.thickness for r in ribbons], dtype=float), tt[0], tt[-1])
    if not ribbons or forward.X_released is None:
        return Optimization(list(ribbons), tau0, tau0, float("nan"), float("nan"), 0, 0, 0, "no ribbons",
                            time.perf_counter() - t0, 0)
    mesh = reference_mesh(np.asarray(flat_uv, dtype=float), np.asarray(target_V, dtype=float),
                          np.asarray(F, dtype=np.int64), faces, force=True)
    model = layout_model(mesh.uv, mesh.F, mesh.target, ribbons, prestretch=prestretch,
                         ribbon_width=ribbon_width, table=table, material=material)
    fun = Objective(model, interpolate(mesh.uv, forward.uv, forward.F, forward.X_released))
    best = {"J": np.inf, "tau": tau0}
    J0 = fun(tau0)[0]                   # the forward layout's objective: always evaluated
    best.update(J=J0)
    f = _bounded(fun, t0, budget_s, max_evaluations, best)
    iterations = [0]

    def step(tau: np.ndarray) -> None:
        iterations[0] += 1
        if progress is not None:
            progress(min((time.perf_counter() - t0) / budget_s, 1.0),
                     f"iteration {iterations[0]}: RMS distance {100 * np.sqrt(best['J']):.2f} % of the diagonal")
    try:
        r = minimize(f, tau0, jac=True, method="L-BFGS-B", bounds=[(tt[0], tt[-1])] * len(tau0), callback=step,
                     options={"maxiter": max_evaluations, "maxfun": max_evaluations, "ftol": 1e-6, "gtol": 1e-7})
        stopped = "converged" if r.success else "evaluation cap"
    except _Budget as exc:
        stopped = str(exc)
    tau = np.clip(best["tau"], tt[0], tt[-1])
    out = [rb.model_copy(update={"thickness": float(t)}) for rb, t in zip(ribbons, tau)]
    return Optimization(out, tau, tau0, J0, float(best["J"]), iterations[0], fun.evaluations,
                        fun.newton_iterations, stopped, time.perf_counter() - t0, len(mesh.F))
