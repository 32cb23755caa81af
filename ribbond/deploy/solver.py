"""Newton's method for the shell's static equilibrium: min_X E(X) with six degrees of freedom pinned.

Each iteration assembles the gradient and a Hessian (``ShellEnergy``), solves on the free degrees of
freedom with a sparse Cholesky factorization (cholespy, as the rest of the engine) and backtracks
along the step until the energy decreases enough (Armijo), the largest move capped at a tenth of
the size. Six coordinates of three vertices are held fixed, which removes
the rigid motions (the free body has no net force, so they carry no load at equilibrium).

Each iteration first tries the exact Hessian (with a tiny diagonal shift): near a stable equilibrium it
is positive definite and the iteration is Newton's, quadratically convergent. Where it is indefinite
(the sheet under compression, the flat start) the factorization fails and the positive semidefinite
approximation of ``ShellEnergy.gradient_and_hessian(project=True)`` is used for that iteration.

It stops when the step and the relative energy decrease are both tiny (converged), when no decrease is
left to find, or at the cap.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ribbond.design.linalg import SymmetricFactor

from .shell import ShellEnergy

__all__ = ["NewtonResult", "pinned_dofs", "newton"]

_FD_LOCK = threading.Lock()


@contextlib.contextmanager
def _quiet_fds() -> Iterator[None]:
    """Silence file descriptors 1 and 2 (C libraries' own prints) for the duration."""
    with _FD_LOCK:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
            saved = [os.dup(1), os.dup(2)]
        except (OSError, ValueError, AttributeError):
            yield
            return
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 1)
            os.dup2(null, 2)
            yield
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in (*saved, null):
                os.close(fd)

#: progress(iteration, energy, gradient norm)
Progress = Callable[[int, float, float], None]


@dataclass(frozen=True)
class NewtonResult:
    """The equilibrium found.

    Attributes
    ----------
    X : (n, 3) positions; energy : E(X); iterations : Newton iterations made;
    converged : the tolerance was met; gradient_norm : ‖∇E‖∞ on the free degrees of freedom;
    time_s : wall time.
    """

    X: np.ndarray
    energy: float
    iterations: int
    converged: bool
    gradient_norm: float
    time_s: float


def pinned_dofs(X: np.ndarray) -> np.ndarray:
    """Six degrees of freedom (indices into the interleaved (3n,) vector) that remove rigid motions.

    Vertex a (nearest the centroid): x, y, z. Vertex b (farthest from a): the two coordinates other
    than the dominant axis of b − a (rotations about the two other axes). Vertex c: the coordinate
    that a rotation about the axis ab moves most.
    """
    X = np.asarray(X, dtype=float)
    c0 = X.mean(axis=0)
    a = int(np.argmin(np.linalg.norm(X - c0, axis=1)))
    b = int(np.argmax(np.linalg.norm(X - X[a], axis=1)))
    ab = X[b] - X[a]
    k = int(np.argmax(np.abs(ab)))
    w = ab / np.linalg.norm(ab)
    rot = np.cross(w, X - X[a])                            # velocity of a rotation about ab
    c = int(np.argmax(np.linalg.norm(rot, axis=1)))
    j = int(np.argmax(np.abs(rot[c])))
    dofs = [3 * a, 3 * a + 1, 3 * a + 2] + [3 * b + i for i in range(3) if i != k] + [3 * c + j]
    if len(set(dofs)) != 6:
        raise ValueError("cannot pin six independent degrees of freedom: the mesh is degenerate")
    return np.array(dofs, dtype=np.int64)


def newton(energy: ShellEnergy, X0: np.ndarray, *, max_iterations: int = 200, tolerance: float = 1e-9,
           step_tolerance: float = 1e-7, progress: Progress | None = None,
           scale: float | None = None, hessian: str = "regularized") -> NewtonResult:
    """Minimize ``energy`` from X0 (n, 3) by projected Newton with a backtracking line search.

    Parameters
    ----------
    tolerance : relative energy decrease |ΔE| / max(|E|, E_ref) below which, with a small step,
        the iteration has converged.
    step_tolerance : largest vertex move, as a fraction of ``scale`` (default: the bounding-box
        diagonal of X0), below which a step is small.
    progress : called after each iteration with (iteration, energy, ‖∇E‖∞).
    hessian : ``"regularized"``: the exact Hessian plus μ·mean|diag|·I, μ raised ×100 until the
        Cholesky factorization succeeds and the step descends, lowered ×10 after each success
        (near the equilibrium it is Newton's method, quadratic); ``"projected"``: the per-element
        projected Hessian (always positive semidefinite; converges only linearly where the sheet is
        under compression, whose negative curvature it discards).
    """
    if hessian not in ("regularized", "projected"):
        raise ValueError(f"hessian must be 'regularized' or 'projected', not {hessian!r}")
    t0 = time.perf_counter()
    X = np.array(X0, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or not np.all(np.isfinite(X)):
        raise ValueError(f"the start positions must be a finite (n, 3) array, got shape {X.shape}")
    n3 = X.size
    pins = pinned_dofs(X)
    free = np.setdiff1d(np.arange(n3), pins)
    scale = float(scale if scale is not None else np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
    E = energy.energy(X)
    e_ref = max(abs(E), 1e-30)
    mu_rel = 1e-9
    converged = False
    gnorm = np.inf
    it = 0
    for it in range(1, max_iterations + 1):
        g, exact, psd = energy.gradient_and_hessians(X)
        gf = g[free]
        gnorm = float(np.abs(gf).max())
        accepted = False
        alpha, En, d = 0.0, E, np.zeros_like(gf)
        kinds = ("exact", "psd") if hessian == "regularized" else ("psd",)
        for kind in kinds:
            Hf = (exact() if kind == "exact" else psd())[free][:, free].tocsc()
            dmean = float(np.mean(np.abs(Hf.diagonal()))) or 1.0
            mu = (mu_rel if kind == "exact" else 1e-8) * dmean
            try:
                with _quiet_fds():                     # CHOLMOD prints "not positive definite" on stdout
                    fac = SymmetricFactor(Hf + sp.identity(len(free), format="csc") * mu)
                d = -fac.solve(gf)
            except (RuntimeError, ValueError):
                continue                               # indefinite: the positive semidefinite one
            slope = float(d @ gf)
            if not np.all(np.isfinite(d)) or slope >= 0:
                continue
            if -slope <= 1e-13 * e_ref:                # no decrease left to find: at the minimum
                converged = True
                break
            # backtracking (Armijo); the largest move at most a tenth of the size
            dmax = float(np.abs(d).max())
            alpha = min(1.0, 0.1 * scale / dmax)
            while alpha > 1e-8:
                Xn = X.ravel().copy()
                Xn[free] += alpha * d
                Xn = Xn.reshape(-1, 3)
                En = energy.energy(Xn)
                if np.isfinite(En) and En <= E + 1e-4 * alpha * slope:
                    accepted = True
                    break
                alpha *= 0.5
            if accepted:
                break
        if converged:
            if progress is not None:
                progress(it, E, gnorm)
            break
        if not accepted:
            break
        step = alpha * float(np.abs(d).max())
        dE = E - En
        X, E = Xn, En
        e_ref = max(e_ref, abs(E))
        if progress is not None:
            progress(it, E, gnorm)
        if dE <= tolerance * e_ref and step <= step_tolerance * scale:
            converged = True
            break
    return NewtonResult(X=X, energy=float(E), iterations=it, converged=converged, gradient_norm=gnorm,
                        time_s=time.perf_counter() - t0)
