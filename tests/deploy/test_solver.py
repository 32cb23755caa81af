"""Newton's method: the pinned degrees of freedom remove exactly the rigid motions, and the
iteration reaches known equilibria (bare fabric: the sheet contracted by 1/s)."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy.shell import ShellEnergy, edge_basis_forms
from ribbond.deploy.solver import newton, pinned_dofs
from ribbond.design import surfaces


def _rigid_basis(X):
    """(3n, 6) the infinitesimal rigid motions of X: three translations, three rotations."""
    n = len(X)
    B = np.zeros((3 * n, 6))
    for k in range(3):
        B[k::3, k] = 1.0
        axis = np.eye(3)[k]
        B[:, 3 + k] = np.cross(axis, X).ravel()
    return B


@pytest.mark.parametrize("maker", [lambda: surfaces.saddle(rings=6), lambda: surfaces.cylinder_patch(n_around=8, n_along=4)])
def test_pins_remove_the_six_rigid_motions(maker):
    X, _ = maker()
    pins = pinned_dofs(X)
    assert len(set(pins.tolist())) == 6
    assert np.linalg.matrix_rank(_rigid_basis(X)[pins]) == 6


def test_bare_sheet_contracts_by_one_over_s():
    s = 1.6
    UV, F = surfaces.grid(12, 8)
    uv = UV * np.array([60.0, 40.0])
    m = len(F)
    abar = edge_basis_forms(uv, F, np.tile(np.eye(2) / s ** 2, (m, 1, 1)))
    E = ShellEnergy(F, abar, np.zeros((m, 3)), np.ones(m), 0.01 * np.ones(m), 0.3)
    rng = np.random.default_rng(0)
    X0 = np.column_stack([uv / 1.3, 0.5 * rng.standard_normal(len(uv))])
    r = newton(E, X0)
    assert r.converged
    X = r.X
    e1, e2 = X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
    assert area == pytest.approx(60.0 * 40.0 / s ** 2, rel=1e-6)
    assert r.energy < 1e-9 * E.energy(X0)


def test_progress_is_reported_and_the_energy_decreases():
    UV, F = surfaces.grid(6, 6)
    uv = UV * 30.0
    m = len(F)
    abar = edge_basis_forms(uv, F, np.tile(0.5 * np.eye(2), (m, 1, 1)))
    E = ShellEnergy(F, abar, np.zeros((m, 3)), np.ones(m), 0.01 * np.ones(m), 0.3)
    seen = []
    X0 = np.column_stack([uv, np.sin(uv[:, 0] / 10.0)])
    r = newton(E, X0, progress=lambda i, e, g: seen.append((i, e)))
    assert [i for i, _ in seen] == list(range(1, r.iterations + 1))
    energies = [e for _, e in seen]
    assert all(b <= a for a, b in zip(energies, energies[1:]))
    assert energies[-1] == pytest.approx(r.energy)


def test_bad_start_is_refused():
    UV, F = surfaces.grid(2, 2)
    m = len(F)
    E = ShellEnergy(F, edge_basis_forms(UV, F, np.tile(np.eye(2), (m, 1, 1))), np.zeros((m, 3)),
                    np.ones(m), np.ones(m), 0.3)
    with pytest.raises(ValueError, match="finite"):
        newton(E, np.full((len(UV), 3), np.nan))
    with pytest.raises(ValueError, match="hessian"):
        newton(E, np.column_stack([UV, np.zeros(len(UV))]), hessian="bfgs")


def test_factor_reused_on_its_pattern_solves_and_tells_definiteness():
    """The Cholesky analysed once (Newton's reuse) solves each matrix of that pattern, tells an
    indefinite one, and still solves after such a failure."""
    import scipy.sparse as sp

    from ribbond.deploy.solver import _Factor

    rng = np.random.default_rng(2)
    n = 40
    L = sp.random(n, n, density=0.1, random_state=3) + sp.identity(n)
    A = (L @ L.T + sp.identity(n)).tocsc()
    A.sort_indices()
    b = rng.standard_normal(n)
    fac = _Factor(A)
    assert fac.factor(A)
    np.testing.assert_allclose(A @ fac.solve(b), b, atol=1e-10)
    shifted = A.copy()
    shifted.data[A.indices == np.repeat(np.arange(n), np.diff(A.indptr))] -= 1.5 * abs(A).max()
    assert np.linalg.eigvalsh(shifted.toarray()).min() < 0
    assert not fac.factor(shifted)
    assert fac.factor(2.0 * A)
    np.testing.assert_allclose((2.0 * A) @ fac.solve(b), b, atol=1e-10)
