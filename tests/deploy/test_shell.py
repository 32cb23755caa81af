"""The shell energy: every gradient and Hessian against central finite differences, the topology,
the sign convention of the hinge quantity, and a discrete cylinder at rest."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy.shell import (E_TO_X, ShellEnergy, _HingeGeometry, edge_basis_forms, hinge_tan,
                                  quadratic_form, shell_topology, stretch_energy)
from ribbond.design import surfaces

H = 1e-6


def _mesh(seed: int = 0):
    V, F = surfaces.cylinder_patch(radius=20.0, angle_deg=90.0, height=20.0, n_around=4, n_along=3)
    rng = np.random.default_rng(seed)
    return V + 0.4 * rng.standard_normal(V.shape), F, rng


def _random_forms(uv, F, rng):
    m = len(F)
    A = 0.7 * np.eye(2) + 0.15 * rng.standard_normal((m, 2, 2))
    A = A @ np.swapaxes(A, 1, 2) + 0.05 * np.eye(2)
    B = 0.02 * rng.standard_normal((m, 2, 2))
    return edge_basis_forms(uv, F, A), edge_basis_forms(uv, F, B + np.swapaxes(B, 1, 2))


def test_quadratic_form_reproduces_traces():
    rng = np.random.default_rng(1)
    P = rng.standard_normal((5, 2, 2))
    P = P @ np.swapaxes(P, 1, 2)
    X = rng.standard_normal((5, 2, 2))
    X = X + np.swapaxes(X, 1, 2)
    Q, l = quadratic_form(P)
    xv = np.stack([X[:, 0, 0], X[:, 0, 1], X[:, 1, 1]], -1)
    PX = P @ X
    np.testing.assert_allclose(np.einsum("ki,kij,kj->k", xv, Q, xv), np.trace(PX @ PX, axis1=1, axis2=2))
    np.testing.assert_allclose(np.einsum("ki,ki->k", l, xv), np.trace(PX, axis1=1, axis2=2))


def test_topology_hinges_are_oriented_and_complete():
    _, F = surfaces.grid(3, 2)
    topo = shell_topology(F)
    m = len(F)
    assert topo.n_edges == (3 * m + topo.boundary_edge.sum()) // 2
    assert len(topo.hinge) == topo.n_edges - topo.boundary_edge.sum()
    # (v0, v1, v2) is a face of F with its winding, (v2, v1, v3) the other
    faces = {tuple(np.roll(f, k)) for f in F.tolist() for k in range(3)}
    for v0, v1, v2, v3 in topo.hinge.tolist():
        assert (v0, v1, v2) in faces and (v2, v1, v3) in faces
    with pytest.raises(ValueError, match="consistently oriented"):
        shell_topology(np.array([[0, 1, 2], [1, 2, 3]]))     # edge 1-2 runs 1 -> 2 in both


def test_hinge_sign_positive_when_bulging_toward_the_normal():
    # two faces of a roof whose ridge is the x axis, normal +z: bulges toward +n
    for drop, sign in ((0.3, 1.0), (-0.3, -1.0)):
        X = np.array([[0.5, 1.0, -drop], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, -1.0, -drop]])
        s, _, _ = hinge_tan(X, np.array([[0, 1, 2, 3]]))
        theta = 2 * np.arctan(abs(drop))          # each face tilts by atan(drop / 1)
        assert np.sign(s[0]) == sign
        assert s[0] == pytest.approx(sign * np.tan(theta / 2), rel=1e-12)


def test_hinge_gradient_and_hessian_match_finite_differences():
    X, F, _ = _mesh()
    hinge = shell_topology(F).hinge
    s, g, Hs = hinge_tan(X, hinge, derivatives=2)
    fd_g = np.zeros_like(g)
    fd_H = np.zeros_like(Hs)
    for j in range(12):
        v, c = hinge[:, j // 3], j % 3
        Xp, Xm = X.copy(), X.copy()
        # perturb each hinge's own vertex (vertices are shared between hinges: one hinge at a time)
        for k in range(len(hinge)):
            Xp[:] = X
            Xm[:] = X
            Xp[v[k], c] += H
            Xm[v[k], c] -= H
            sp_, gp, _ = hinge_tan(Xp, hinge[k:k + 1], derivatives=1)
            sm, gm, _ = hinge_tan(Xm, hinge[k:k + 1], derivatives=1)
            fd_g[k, j] = (sp_[0] - sm[0]) / (2 * H)
            fd_H[k, :, j] = (gp[0] - gm[0]) / (2 * H)
    np.testing.assert_allclose(g, fd_g, atol=1e-7 * np.abs(g).max())
    np.testing.assert_allclose(Hs, fd_H, atol=1e-6 * np.abs(Hs).max())
    np.testing.assert_allclose(Hs, np.swapaxes(Hs, 1, 2), atol=1e-12 * np.abs(Hs).max())


def test_stretch_gradient_and_hessian_match_finite_differences():
    X, F, rng = _mesh(2)
    uv = X[:, 1:3]
    abar, _ = _random_forms(uv, F, rng)
    coef = rng.random(len(F)) + 0.5
    W, g, He = stretch_energy(X, F, abar, coef, 0.3, derivatives=2)
    Hx = E_TO_X.T @ He @ E_TO_X
    for k in range(len(F)):
        for j in range(9):
            v, c = F[k, j // 3], j % 3
            Xp, Xm = X.copy(), X.copy()
            Xp[v, c] += H
            Xm[v, c] -= H
            Wp, gp, _ = stretch_energy(Xp, F[k:k + 1], abar[k:k + 1], coef[k:k + 1], 0.3, derivatives=1)
            Wm, gm, _ = stretch_energy(Xm, F[k:k + 1], abar[k:k + 1], coef[k:k + 1], 0.3, derivatives=1)
            assert (Wp[0] - Wm[0]) / (2 * H) == pytest.approx(g[k, j], abs=1e-6 * np.abs(g).max())
            np.testing.assert_allclose((gp[0] - gm[0]) / (2 * H), Hx[k, :, j], atol=1e-5 * np.abs(Hx).max())


def test_stretch_energy_vanishes_at_the_rest_metric():
    V, F = surfaces.grid(3, 3)
    uv = V * 10.0
    X = np.column_stack([0.8 * uv[:, 0], 0.6 * uv[:, 1], np.zeros(len(uv))])   # a = diag(0.64, 0.36)
    abar = edge_basis_forms(uv, F, np.tile(np.diag([0.64, 0.36]), (len(F), 1, 1)))
    W, g, _ = stretch_energy(X, F, abar, np.ones(len(F)), 0.3, derivatives=1)
    assert np.abs(W).max() < 1e-12 and np.abs(g).max() < 1e-9


@pytest.mark.parametrize("seed", [3, 4])
def test_shell_energy_gradient_and_exact_hessian_match_finite_differences(seed):
    X, F, rng = _mesh(seed)
    abar, bbar = _random_forms(X[:, 1:3], F, rng)
    E = ShellEnergy(F, abar, bbar, rng.random(len(F)) + 0.5, rng.random(len(F)) + 0.5, 0.3)
    g, Hm = E.gradient_and_hessian(X, project=False)
    x = X.ravel()
    fd_g = np.zeros_like(x)
    fd_H = np.zeros((len(x), len(x)))
    for j in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[j] += H
        xm[j] -= H
        fd_g[j] = (E.energy(xp.reshape(-1, 3)) - E.energy(xm.reshape(-1, 3))) / (2 * H)
        fd_H[:, j] = (E.gradient(xp.reshape(-1, 3)) - E.gradient(xm.reshape(-1, 3))) / (2 * H)
    np.testing.assert_allclose(g, fd_g, atol=1e-6 * np.abs(g).max())
    np.testing.assert_allclose(E.gradient(X), g, atol=1e-14 * np.abs(g).max())
    np.testing.assert_allclose(Hm.toarray(), fd_H, atol=1e-6 * np.abs(fd_H).max())


def test_projected_hessian_is_positive_semidefinite():
    X, F, rng = _mesh(5)
    abar, bbar = _random_forms(X[:, 1:3], F, rng)
    E = ShellEnergy(F, abar, bbar, np.ones(len(F)), np.ones(len(F)), 0.3)
    _, Hp = E.gradient_and_hessian(X, project=True)
    w = np.linalg.eigvalsh(Hp.toarray())
    assert w.min() > -1e-10 * w.max()
    _, He = E.gradient_and_hessian(0.3 * X, project=False)             # compressed: the exact one is not
    assert np.linalg.eigvalsh(He.toarray()).min() < -1e-6 * w.max()


def test_cylinder_at_its_rest_curvature_has_no_bending_energy():
    """A cylinder of radius R unrolled isometrically: rest metric the identity, rest curvature 1/R
    around; its bending energy is that of the rest curvature's mismatch, which vanishes at R
    (up to the discretization) and not at other radii."""
    R = 30.0
    UV, F = surfaces.grid(24, 12)
    uv = UV * np.array([np.pi / 2 * R, 40.0])
    m = len(F)
    abar = edge_basis_forms(uv, F, np.tile(np.eye(2), (m, 1, 1)))

    def bending(radius_rest, radius):
        bbar = edge_basis_forms(uv, F, np.tile(np.diag([1.0 / radius_rest, 0.0]), (m, 1, 1)))
        E = ShellEnergy(F, abar, bbar, np.zeros(m), np.ones(m), 0.3)
        t = uv[:, 0] / radius
        # z = R (cos t − 1): the edges drop, the centre of curvature is below: a bulge toward +z = +n
        X = np.column_stack([radius * np.sin(t), uv[:, 1], radius * (np.cos(t) - 1)])
        return E.parts(X)[1]

    flat_energy = bending(R, 1e6)
    assert bending(R, R) < 1e-3 * flat_energy
    assert bending(R, 0.8 * R) > 0.02 * flat_energy
    assert bending(R, 1.25 * R) > 0.02 * flat_energy


def test_hessian_on_the_free_dofs_is_the_full_one_restricted():
    """The fixed-pattern assembly on a subset of dofs (the solver's pinned ones left out) gives the
    rows and columns of the full Hessian (itself checked by finite differences above), in CSC order."""
    X, F, rng = _mesh(6)
    abar, bbar = _random_forms(X[:, 1:3], F, rng)
    E = ShellEnergy(F, abar, bbar, rng.random(len(F)) + 0.5, rng.random(len(F)) + 0.5, 0.3)
    free = np.setdiff1d(np.arange(X.size), [0, 1, 2, 7, 8, 20])
    g_all, exact_all, psd_all = E.gradient_and_hessians(X)
    g, exact, psd = E.gradient_and_hessians(X, free)
    np.testing.assert_array_equal(g, g_all)
    for sub, full in ((exact, exact_all), (psd, psd_all)):
        A, B = sub(), full()
        assert A.format == "csc" and A.shape == (len(free), len(free))
        np.testing.assert_allclose(A.toarray(), B.toarray()[np.ix_(free, free)], atol=1e-12 * abs(B).max())
        C = A.copy()
        C.sort_indices()
        np.testing.assert_array_equal(C.indices, A.indices)
    assert E.gradient_and_hessians(X, free.copy())[1]().nnz == exact().nnz     # same pattern reused
    # the solver's: the lower triangle only, the same values
    _, exact_low, psd_low = E.gradient_and_hessians(X, free, lower=True)
    for low, sub in ((exact_low, exact), (psd_low, psd)):
        L, A = low(), sub()
        assert L.format == "csc" and np.all(L.indices >= np.repeat(np.arange(len(free)), np.diff(L.indptr)))
        np.testing.assert_array_equal(L.toarray(), np.tril(A.toarray()))


def _cross_matrices(v):
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _dense_hinge_hessian(X, hinge):
    """The hinge Hessian as first written (before the batch-last rewrite): the dense J (9, 12) of
    u = (N_f, N_g, e), the 9 × 9 ∂²s/∂u² and Jᵀ M J, plus N_f's and N_g's second derivatives."""
    v0, v1, v2, v3 = (X[hinge[:, k]] for k in range(4))
    Nf, Ng, e = np.cross(v1 - v0, v2 - v0), np.cross(v1 - v2, v3 - v2), v2 - v1
    nf, ng, L = (np.linalg.norm(a, axis=1) for a in (Nf, Ng, e))
    Q = nf * ng + np.einsum("ki,ki->k", Nf, Ng)
    D = L * Q
    s = np.einsum("ki,ki->k", np.cross(Nf, Ng), e) / D
    Nfh, Ngh, eh = Nf / nf[:, None], Ng / ng[:, None], e / L[:, None]
    gQf, gQg = ng[:, None] * Nfh + Ng, nf[:, None] * Ngh + Nf
    c = s / D
    gs = (np.cross(Ng, e) / D[:, None] - (c * L)[:, None] * gQf,
          np.cross(e, Nf) / D[:, None] - (c * L)[:, None] * gQg,
          np.cross(Nf, Ng) / D[:, None] - (c * Q)[:, None] * eh)
    h, eye, outer = len(s), np.eye(3), (lambda a, b: a[:, :, None] * b[:, None, :])
    J = np.zeros((h, 9, 12))
    w = (v2 - v1, v0 - v2, v1 - v0, v3 - v1, v2 - v3, v1 - v2)
    for (ub, xb), wk in zip(((0, 0), (0, 1), (0, 2), (1, 2), (1, 1), (1, 3)), w):
        J[:, 3 * ub:3 * ub + 3, 3 * xb:3 * xb + 3] = _cross_matrices(wk)
    J[:, 6:9, 6:9], J[:, 6:9, 3:6] = eye, -eye
    C = [_cross_matrices(a / D[:, None]) for a in (e, Nf, Ng)]
    cL = (c * L)[:, None, None]
    M = np.zeros((h, 9, 9))
    M[:, 0:3, 0:3] = -(cL * (ng / nf)[:, None, None]) * (eye - outer(Nfh, Nfh))
    M[:, 3:6, 3:6] = -(cL * (nf / ng)[:, None, None]) * (eye - outer(Ngh, Ngh))
    M[:, 0:3, 3:6] = -C[0] - cL * (outer(Nfh, Ngh) + eye)
    M[:, 3:6, 0:3] = np.swapaxes(M[:, 0:3, 3:6], 1, 2)
    M[:, 0:3, 6:9], M[:, 6:9, 0:3], M[:, 3:6, 6:9], M[:, 6:9, 3:6] = C[2], -C[2], -C[1], C[1]
    M[:, 6:9, 6:9] = -(c * Q / L)[:, None, None] * (eye - outer(eh, eh))
    U = np.concatenate([np.concatenate(gs, 1)[:, None], np.concatenate([0 * eh, 0 * eh, eh], 1)[:, None]], 1)
    V = np.concatenate([np.concatenate([(L / D)[:, None] * gQf, (L / D)[:, None] * gQg, (Q / D)[:, None] * eh],
                                       1)[:, None],
                        np.concatenate([c[:, None] * gQf, c[:, None] * gQg, 0 * eh], 1)[:, None]], 1)
    R = np.swapaxes(U, 1, 2) @ V
    M -= R + np.swapaxes(R, 1, 2)
    hess = np.swapaxes(J, 1, 2) @ M @ J
    Xf, Xg = _cross_matrices(gs[0]), _cross_matrices(gs[1])
    for i, j, blk in ((0, 1, -Xf), (0, 2, Xf), (1, 2, Xg - Xf), (2, 3, Xg), (1, 3, -Xg)):
        hess[:, 3 * i:3 * i + 3, 3 * j:3 * j + 3] += blk
        hess[:, 3 * j:3 * j + 3, 3 * i:3 * i + 3] -= blk
    return s, np.concatenate(gs, 1), hess


def test_hinge_hessian_is_the_dense_formula_and_its_weighted_form_the_weighted_one():
    X, F, rng = _mesh(5)
    hinge = shell_topology(F).hinge
    s_ref, _, H_ref = _dense_hinge_hessian(X, hinge)
    s, g, Hs = hinge_tan(X, hinge, derivatives=2)
    scale = np.abs(H_ref).max()
    np.testing.assert_allclose(s, s_ref, rtol=1e-13)
    np.testing.assert_allclose(Hs, H_ref, atol=1e-13 * scale)
    weight = rng.standard_normal(len(hinge))
    hg = _HingeGeometry(X, hinge)
    Hw = hg.hessian(weight)                                        # batch-last (12, 12, h)
    np.testing.assert_allclose(np.moveaxis(Hw, 2, 0), weight[:, None, None] * H_ref, atol=1e-13 * scale)


@pytest.mark.parametrize("seed", [5, 6])
def test_rest_sensitivities_match_finite_differences(seed):
    """∂(vᵀ∇E)/∂b̄, /∂stretch_coef, /∂bend_coef (the optimization's adjoint) against central
    differences of vᵀ∇E in each face parameter (∇E is linear in each: the differences are exact up
    to rounding)."""
    X, F, rng = _mesh(seed)
    abar, bbar = _random_forms(X[:, 1:3], F, rng)
    cs, cb = rng.random(len(F)) + 0.5, rng.random(len(F)) + 0.5
    v = rng.standard_normal(3 * len(X))
    d_bbar, d_stretch, d_bend = ShellEnergy(F, abar, bbar, cs, cb, 0.3).rest_sensitivities(X, v)

    def h(bb=bbar, s=cs, b=cb):
        return float(v @ ShellEnergy(F, abar, bb, s, b, 0.3).gradient(X))

    fd_bbar = np.zeros_like(bbar)
    fd_stretch, fd_bend = np.zeros(len(F)), np.zeros(len(F))
    for f in range(len(F)):
        for j in range(3):
            bp, bm = bbar.copy(), bbar.copy()
            bp[f, j] += H
            bm[f, j] -= H
            fd_bbar[f, j] = (h(bb=bp) - h(bb=bm)) / (2 * H)
        e = np.zeros(len(F))
        e[f] = H
        fd_stretch[f] = (h(s=cs + e) - h(s=cs - e)) / (2 * H)
        fd_bend[f] = (h(b=cb + e) - h(b=cb - e)) / (2 * H)
    assert np.abs(d_bbar).max() > 0 and np.abs(d_stretch).max() > 0 and np.abs(d_bend).max() > 0
    np.testing.assert_allclose(d_bbar, fd_bbar, atol=1e-6 * np.abs(fd_bbar).max())
    np.testing.assert_allclose(d_stretch, fd_stretch, atol=1e-6 * np.abs(fd_stretch).max())
    np.testing.assert_allclose(d_bend, fd_bend, atol=1e-6 * np.abs(fd_bend).max())
