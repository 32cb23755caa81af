"""Sparse symmetric positive definite systems, factorized once and solved many times.

The flattening (Eq. 9) and the stripe patterns (inverse power iteration) both solve one matrix
against many right-hand sides; the factorization is their expensive set-up and is done once.

Two back ends give ``SymmetricFactor`` the same API:

- ``"cholespy"``: CHOLMOD's sparse Cholesky (the cholespy package), used where it is installed. Its
  back-substitution is 1.7-2x faster than SuperLU's on the flattening's cotangent Laplacian (at 112k
  faces, two right-hand sides: 12.6 against 24.9 ms on the torus patch, 23.8 against 40.2 ms on the
  saddle), and that solve runs every iteration; the factorizations take about as long.
- ``"scipy"``: SuperLU (scipy), with the minimum-degree ordering of Lᵀ + L that suits a symmetric
  matrix, the fallback where cholespy has no wheel (linux/aarch64: Raspberry Pi hosts). The same
  solutions to rounding (1e-13 relative on these matrices); the flattening's path is sensitive to
  rounding, so its iteration count on a given mesh may differ between the two.

``BACKEND`` names the one in use; ``SymmetricFactor(L, backend=...)`` asks for one explicitly.
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

try:
    from cholespy import CholeskySolverD, MatrixType
except ImportError:  # no wheel on linux/aarch64: pyproject.toml installs it only where it has one
    CholeskySolverD = MatrixType = None

#: The back ends, by name: what each needs installed.
BACKENDS = ("cholespy", "scipy")

#: The back end ``SymmetricFactor`` uses unless asked: cholespy where installed, else scipy.
BACKEND = "cholespy" if CholeskySolverD is not None else "scipy"

#: What ``BACKEND`` means, for logs and the design's progress lines.
BACKEND_DESCRIPTION = {
    "cholespy": "cholespy (CHOLMOD sparse Cholesky)",
    "scipy": "scipy SuperLU (cholespy is not installed)",
}[BACKEND]

log = logging.getLogger(__name__)
_announced = False


class _CholmodFactor:
    """cholespy's CHOLMOD factor of a CSC matrix."""

    def __init__(self, L: sp.csc_matrix) -> None:
        self._chol = CholeskySolverD(L.shape[0], L.indptr.astype(np.int32), L.indices.astype(np.int32),
                                     L.data.astype(np.float64), MatrixType.CSC)

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = np.empty_like(b)
        self._chol.solve(b, x)
        return x


class _SuperLUFactor:
    """scipy's SuperLU factor of a CSC matrix, ordered by minimum degree on Lᵀ + L (symmetric)."""

    def __init__(self, L: sp.csc_matrix) -> None:
        self._lu = spla.splu(L, permc_spec="MMD_AT_PLUS_A")

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(b)


def _announce() -> None:
    """Log once per process which back end the engine's sparse solves use."""
    global _announced
    if not _announced:
        _announced = True
        log.info("sparse solver: %s", BACKEND_DESCRIPTION)


class SymmetricFactor:
    """A sparse symmetric positive definite matrix ``L`` (k, k), factorized on construction.

    ``solve(b)`` takes b of shape (k,) or (k, c) and returns x with L x = b.

    Parameters
    ----------
    L : (k, k) sparse symmetric positive definite.
    backend : "cholespy" or "scipy" (see the module's docstring); default ``BACKEND``.
    """

    def __init__(self, L: sp.spmatrix, backend: str | None = None) -> None:
        backend = BACKEND if backend is None else backend
        if backend not in BACKENDS:
            raise ValueError(f"unknown sparse solver back end {backend!r}; expected one of {BACKENDS}")
        if backend == "cholespy" and CholeskySolverD is None:
            raise ValueError("the sparse solver back end 'cholespy' is not installed (no wheel for "
                             "this machine); use 'scipy'")
        L = sp.csc_matrix(L)
        if L.shape[0] != L.shape[1]:
            raise ValueError(f"the matrix to factorize must be square, got {L.shape}")
        _announce()
        self.n = L.shape[0]
        self.backend = backend
        self._factor = _CholmodFactor(L) if backend == "cholespy" else _SuperLUFactor(L)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x (k,) or (k, c) with L x = b."""
        b = np.ascontiguousarray(b, dtype=np.float64)
        if b.shape[0] != self.n:
            raise ValueError(f"the right-hand side has {b.shape[0]} rows, the matrix {self.n}")
        return self._factor.solve(b)


class TwoLevelSolver:
    """A sparse Hermitian positive definite M (m, m), solved by conjugate gradients with a two-level
    preconditioner: the Galerkin coarse problem Pᴴ M P on the columns of P (factorized once), plus
    Jacobi.

    The coarse space carries the smooth part of a solution (what varies slowly over a patch), which
    plain CG would need many iterations to propagate. Without ``x0`` the start is the coarse solution.

    Parameters
    ----------
    M : (m, m) sparse Hermitian positive definite.
    P : (m, k) sparse prolongation from the coarse space, k ≪ m.
    rtol, max_iterations : CG's relative residual tolerance and iteration cap.
    """

    def __init__(self, M: sp.spmatrix, P: sp.spmatrix, *, rtol: float = 1e-6,
                 max_iterations: int = 500) -> None:
        import scipy.sparse.linalg as spla

        self.M = sp.csr_matrix(M)
        self.P = sp.csr_matrix(P)
        self.PH = self.P.conj().T.tocsr()
        self._coarse = spla.splu((self.PH @ self.M @ self.P).tocsc())
        self._inv_diag = 1.0 / self.M.diagonal().real
        self.rtol, self.max_iterations = rtol, max_iterations
        dtype = np.result_type(self.M.dtype, self.P.dtype)
        self._pre = spla.LinearOperator(self.M.shape, matvec=self._precondition, dtype=dtype)

    def coarse_solve(self, b_coarse: np.ndarray) -> np.ndarray:
        """(k,) the solution of the coarse problem Pᴴ M P y = ``b_coarse``."""
        return self._coarse.solve(b_coarse)

    def _precondition(self, r: np.ndarray) -> np.ndarray:
        return self.P @ self._coarse.solve(self.PH @ r) + self._inv_diag * r

    def solve(self, b: np.ndarray, x0: np.ndarray | None = None,
              rtol: float | None = None) -> tuple[np.ndarray, bool]:
        """x (m,) with M x = b (to ``rtol``, default the solver's), and whether CG met the tolerance
        within its iteration cap."""
        import scipy.sparse.linalg as spla

        if x0 is None:
            x0 = self.P @ self._coarse.solve(self.PH @ b)
        x, info = spla.cg(self.M, b, x0=x0, rtol=self.rtol if rtol is None else rtol, M=self._pre,
                          maxiter=self.max_iterations)
        return x, info == 0
