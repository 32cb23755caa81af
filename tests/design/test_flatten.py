"""The bounded directional flattening (§4, Appendices A-B) on analytic surfaces."""

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.curvature import face_curvature
from ribbond.design.flatten import (BoundedFlattener, RowCountCoupling, exact_rotation_stretch, local_step,
                                    optimal_rotation, principal_stretches, row_curl_operator)
from ribbond.design.frames import face_frames
from ribbond.design.line_field import ANISOTROPY_THRESHOLD, curvature_line_field
from ribbond.design.params import DesignParameters, SolverSettings
from ribbond.design.report import BAD_TOLERANCE, bounds_deviation

BOUNDS = DesignParameters().bounds


def flatten(V, F, **settings):
    fr = face_frames(V, F)
    lf = curvature_line_field(V, F, fr, face_curvature(V, F, fr))
    # as the pipeline does: the row-count phase counts rows where k1 is defined
    solver = BoundedFlattener(V, F, lf.angle, BOUNDS, SolverSettings(**settings), frames=fr,
                              k1_defined=lf.anisotropy > ANISOTROPY_THRESHOLD)
    return fr, lf, solver, solver.solve()


def bad_pct(result):
    (lo1, hi1), (lo2, hi2) = BOUNDS
    d1 = bounds_deviation(result.sigma[:, 0], lo1, hi1)
    d2 = bounds_deviation(result.sigma[:, 1], lo2, hi2)
    return 100 * np.mean(d1 > BAD_TOLERANCE), 100 * np.mean(d2 > BAD_TOLERANCE)


def test_closed_form_rotation_is_eq_7():
    rng = np.random.default_rng(3)
    P = rng.normal(size=(200, 2, 2))                         # includes reflections (det < 0)
    cos, sin = optimal_rotation(P[:, 0, 0], P[:, 0, 1], P[:, 1, 0], P[:, 1, 1])
    for k in range(len(P)):
        U, _, Vt = np.linalg.svd(P[k])
        if np.linalg.det(U @ Vt) < 0:                        # flip U's column of the smallest value
            U[:, 1] *= -1
        R = U @ Vt
        assert np.allclose([[cos[k], -sin[k]], [sin[k], cos[k]]], R, atol=1e-9)


def test_local_step_clamps_eq_5():
    # J = R Σ with Σ outside the bounds: σ̂ are the clamped Σ entries and R is recovered.
    bounds = np.array(BOUNDS)
    a = 0.4
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    for s1, s2 in [(1.1, 1.4), (0.9, 1.4), (1.5, 1.2), (1.2, 1.8)]:
        J = R @ np.diag([s1, s2])
        cos, sin, o1, o2 = local_step(tuple(np.array([x]) for x in J.ravel()), np.ones(1), np.ones(1),
                                      bounds)
        assert np.isclose(np.arctan2(sin[0], cos[0]), a)
        assert np.isclose(o1[0], np.clip(s1, *bounds[0])) and np.isclose(o2[0], np.clip(s2, *bounds[1]))


def random_jacobians(m, seed):
    """(A, B, C, D) of M = J R_θᵀ: half near a rotation times a stretch inside the bounds, half
    far from any (folds, shears), each (m,)."""
    rng = np.random.default_rng(seed)
    phi = rng.uniform(-np.pi, np.pi, m)
    R = np.stack([np.cos(phi), -np.sin(phi), np.sin(phi), np.cos(phi)], axis=1).reshape(m, 2, 2)
    spread = np.where(np.arange(m) % 2 == 0, 0.05, 1.0)[:, None, None]
    M = R @ np.diag(np.mean(BOUNDS, axis=1)) + spread * rng.normal(size=(m, 2, 2))
    return M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1]


def closest_energy(M, cos, sin, s1, s2):
    """‖M − R diag(σ1, σ2)‖²_F per face."""
    A, B, C, D = M
    return ((A - cos * s1) ** 2 + (B + sin * s2) ** 2 + (C - sin * s1) ** 2 + (D - cos * s2) ** 2)


def test_exact_local_step_is_the_closest_bounded_stretch_by_brute_force():
    # Eq. 4 over R ∈ SO(2) and σ_i within the bounds: for each of 4001 angles the best σ is the
    # clamp, so the minimum over that grid bounds the exact step's energy from above.
    bounds = np.array(BOUNDS)
    M = random_jacobians(4000, seed=11)
    cos, sin, s1, s2 = local_step(M, np.ones(4000), np.ones(4000), bounds)
    ours = closest_energy(M, cos, sin, s1, s2)
    assert np.all((s1 >= bounds[0, 0]) & (s1 <= bounds[0, 1]) & (s2 >= bounds[1, 0]) & (s2 <= bounds[1, 1]))
    assert np.allclose(cos ** 2 + sin ** 2, 1.0, atol=1e-14)
    phi = np.linspace(-np.pi, np.pi, 4001)[None, :]
    c, s = np.cos(phi), np.sin(phi)
    A, B, C, D = (x[:, None] for x in M)
    g1 = np.clip(A * c + C * s, *bounds[0])
    g2 = np.clip(D * c - B * s, *bounds[1])
    brute = closest_energy((A, B, C, D), c, s, g1, g2).min(axis=1)
    assert np.all(ours <= brute + 1e-12)
    # and a finer grid around our angle finds nothing better either (the optimum, not a grid point)
    near = np.arctan2(sin, cos)[:, None] + np.linspace(-1e-3, 1e-3, 201)[None, :]
    c, s = np.cos(near), np.sin(near)
    fine = closest_energy((A, B, C, D), c, s, np.clip(A * c + C * s, *bounds[0]),
                          np.clip(D * c - B * s, *bounds[1])).min(axis=1)
    assert np.all(ours <= fine + 1e-12)


def test_exact_local_step_never_raises_eq_3_from_the_previous_rotation_and_stretch():
    bounds = np.array(BOUNDS)
    M = random_jacobians(4000, seed=12)
    rng = np.random.default_rng(13)
    phi = rng.uniform(-np.pi, np.pi, 4000)
    prev1, prev2 = rng.uniform(*bounds[0], 4000), rng.uniform(*bounds[1], 4000)
    before = closest_energy(M, np.cos(phi), np.sin(phi), prev1, prev2)
    after = closest_energy(M, *local_step(M, prev1, prev2, bounds))
    assert np.all(after <= before)
    # the old step (R by Eq. 7, Σ by Eq. 5, twice) is never better than the exact one
    two_pass = closest_energy(M, *local_step(M, prev1, prev2, bounds, sigma2_step=lambda h: h))
    assert np.all(after <= two_pass + 1e-12)


def test_exact_local_step_keeps_a_start_that_is_already_optimal():
    # Σ fixed (degenerate bounds): the best R is Eq. 7's for that Σ, which is also the start
    bounds = np.array([[1.1, 1.1], [1.3, 1.3]])
    M = random_jacobians(500, seed=14)
    A, B, C, D = M
    start = optimal_rotation(1.1 * A, 1.3 * B, 1.1 * C, 1.3 * D)
    cos, sin, s1, s2 = exact_rotation_stretch(M, start, bounds)
    assert np.allclose(cos, start[0], atol=1e-10) and np.allclose(sin, start[1], atol=1e-10)
    assert np.all(s1 == 1.1) and np.all(s2 == 1.3)


def test_principal_stretches_are_singular_values():
    rng = np.random.default_rng(5)
    J = rng.normal(size=(50, 2, 2))
    smax, smin, _ = principal_stretches(J)
    sv = np.linalg.svd(J, compute_uv=False)
    assert np.allclose(smax, sv[:, 0]) and np.allclose(np.abs(smin), sv[:, 1])
    assert np.all((smin < 0) == (np.linalg.det(J) < 0))


def test_cylinder_is_flattened_within_the_bounds_along_the_circumference():
    V, F = surfaces.cylinder_patch(radius=40.0, n_around=40, n_along=16)
    fr, lf, solver, res = flatten(V, F)
    assert res.converged and not res.folded.any()
    assert bad_pct(res) == (0.0, 0.0)
    assert np.degrees(res.deviation.mean()) < 0.5
    assert res.energy / fr.area.sum() < 1e-8                 # developable: Eq. 1 holds exactly
    # The flat surface is the larger one: σ ≥ 1 and σ2 ≥ 1.3 everywhere.
    e1, e2 = res.uv[F[:, 1]] - res.uv[F[:, 0]], res.uv[F[:, 2]] - res.uv[F[:, 0]]
    flat_area = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert np.all(flat_area > fr.area * 1.29)


def test_small_torus_patch_within_bounds_and_outer_half_not():
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg=(0, 60), v_deg=(-30, 30), nu=40, nv=20)
    *_, res = flatten(V, F)
    assert res.converged and bad_pct(res) == (0.0, 0.0)
    # Where σ1 ≈ σ2 ≈ 1.3 (both at the shared bound) the stretch is nearly isotropic and its
    # principal direction barely defined; elsewhere the stretch follows k1 closely.
    anisotropic = res.sigma[:, 1] / res.sigma[:, 0] > 1.03
    assert np.degrees(res.deviation[anisotropic].mean()) < 0.2
    assert np.degrees(res.deviation.mean()) < 1.0
    # The outer half of the torus: σ2 would have to vary by (R + r)/(R) = 1.4 where the bounds
    # allow 1.51/1.3 = 1.16, so it cannot be flattened within them; it still converges.
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg=(0, 180), v_deg=(-90, 90), nu=60, nv=30)
    *_, res = flatten(V, F)
    assert res.converged and not res.folded.any()
    assert sum(bad_pct(res)) > 10


def test_shallow_cap_within_bounds_deep_cap_not():
    *_, shallow = flatten(*surfaces.sphere_cap(radius=80.0, half_angle_deg=20, rings=14))
    assert shallow.converged and bad_pct(shallow) == (0.0, 0.0)
    fr, _, _, deep = flatten(*surfaces.sphere_cap(radius=40.0, half_angle_deg=90, rings=14))
    assert deep.converged and not deep.folded.any()
    assert min(bad_pct(deep)) > 10
    assert deep.energy / fr.area.sum() > 1e3 * shallow.energy / fr.area.sum()


def test_saddle_within_bounds():
    *_, res = flatten(*surfaces.saddle(size=80.0, rings=14))
    assert res.converged and bad_pct(res) == (0.0, 0.0) and not res.folded.any()


def test_plain_local_global_energy_never_rises():
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg=(0, 60), v_deg=(-30, 30), nu=24, nv=12)
    *_, plain = flatten(V, F, anderson_window=0, max_iterations=300)
    energies = np.array([h[0] for h in plain.history])
    assert np.all(np.diff(energies) <= 1e-12 * energies[0])


def test_plain_iterations_with_the_bounds_active_never_raise_eq_3():
    # the exact local step and the exact global step (Eq. 9) are block minimizations of Eq. 3
    V, F = surfaces.sphere_cap(radius=40.0, half_angle_deg=70, rings=8)
    *_, plain = flatten(V, F, anderson_window=0, max_iterations=200, spacing_integrability_weight=0.0)
    energies = np.array([h[0] for h in plain.history])
    assert energies[-1] > 0 and np.all(np.diff(energies) <= 0)


def test_same_input_same_iterations_and_bits():
    V, F = surfaces.saddle(size=80.0, rings=10)
    *_, a = flatten(V, F)
    *_, b = flatten(V, F)
    assert a.iterations == b.iterations and a.uv.tobytes() == b.uv.tobytes()


@pytest.mark.parametrize("surface", ["saddle", "deep_cap"])
def test_a_1e_12_perturbation_changes_the_iterations_by_at_most_10_percent(surface):
    V, F = (surfaces.saddle(size=80.0, rings=12) if surface == "saddle"
            else surfaces.sphere_cap(radius=40.0, half_angle_deg=70, rings=12))
    *_, base = flatten(V, F)
    assert base.converged and base.iterations >= 20
    for seed in (21, 22, 23):
        rng = np.random.default_rng(seed)
        *_, nudged = flatten(V * (1.0 + 1e-12 * rng.standard_normal(V.shape)), F)
        assert nudged.converged and abs(nudged.iterations - base.iterations) <= 0.1 * base.iterations


def test_anderson_reaches_the_same_minimum_in_fewer_iterations():
    # Outside the bounds the minimum of Eq. 3 is positive and its flattening unique (within the
    # bounds a whole family has zero energy, and any of them is a solution).
    V, F = surfaces.sphere_cap(radius=40.0, half_angle_deg=90, rings=8)
    fr, _, _, plain = flatten(V, F, anderson_window=0, max_iterations=20000)
    *_, fast = flatten(V, F)
    assert plain.converged and fast.converged and fast.iterations < plain.iterations / 3
    assert np.isclose(fast.energy, plain.energy, rtol=1e-3)
    assert np.abs(plain.sigma - fast.sigma).max() < 5e-3


def test_flattening_scales_with_the_target():
    V, F = surfaces.saddle(size=60.0, rings=8)
    fr = face_frames(V, F)
    lf = curvature_line_field(V, F, fr, face_curvature(V, F, fr))
    plain = SolverSettings(anderson_window=0, max_iterations=60)   # same steps, no AA choices
    small = BoundedFlattener(V, F, lf.angle, BOUNDS, plain)
    uv0 = small.initial_map()
    a = small.solve(uv0)
    b = BoundedFlattener(3.0 * V, F, lf.angle, BOUNDS, plain).solve(3.0 * uv0)
    assert np.allclose(a.sigma, b.sigma, atol=1e-9)
    assert np.allclose(b.uv, 3.0 * a.uv, atol=1e-7)


def test_bad_arguments_are_refused():
    V, F = surfaces.cylinder_patch(n_around=6, n_along=3)
    with pytest.raises(ValueError, match="k1_angle"):
        BoundedFlattener(V, F, np.zeros(3), BOUNDS)
    with pytest.raises(ValueError, match="bounds"):
        BoundedFlattener(V, F, np.zeros(len(F)), ((1.3, 1.0), (1.3, 1.5)))


def test_coarse_to_fine_start_flattens_within_the_bounds():
    V, F = surfaces.sphere_cap(radius=80.0, half_angle_deg=20, rings=24)     # 3456 faces
    fr, lf, solver, res = flatten(V, F, coarse_faces=600)
    assert res.converged and not res.folded.any()
    assert bad_pct(res) == (0.0, 0.0)
    # The same minimum of Eq. 3 as from the fine mesh's own start: (nearly) zero.
    assert res.energy / fr.area.sum() < 1e-6


def _torus_with_exact_k1(nu, nv, R=50.0, r=20.0):
    V, F = surfaces.torus_patch(R, r, u_deg=(0, 60), v_deg=(-30, 30), nu=nu, nv=nv)
    fr = face_frames(V, F)
    local = fr.to_local(surfaces.torus_curvature(V[F].mean(axis=1), R, r).direction1)
    return V, F, fr, np.arctan2(local[:, 1], local[:, 0])


def test_row_curl_operator_is_the_curl_on_the_torus():
    # k2 runs along the parallels, |k2♭| = ρ dθ with ρ = R + r cos v: curl(k2) = −sin v / ρ
    # (d(ρ dθ) = −r sin v dv ∧ dθ over the area form r ρ dv ∧ dθ), and (1/ρ) k2♭ = dθ is closed.
    R, r = 50.0, 20.0
    V, F, fr, angle = _torus_with_exact_k1(40, 20, R, r)
    C, vertex_area = row_curl_operator(F, fr, angle, len(V))
    interior = np.asarray(abs(C).sum(axis=1)).ravel() > 0
    boundary_count = 2 * (40 + 1) + 2 * (20 - 1)
    assert interior.sum() == len(V) - boundary_count       # only the boundary is left out
    v = np.arctan2(V[:, 2], np.hypot(V[:, 0], V[:, 1]) - R)[interior]
    exact = np.sin(v) / (R + r * np.cos(v))
    curl = (C @ np.ones(len(F)))[interior] / vertex_area[interior]
    # each vertex signs its own k2, so the sign of a row is its own choice
    assert np.allclose(np.abs(curl), np.abs(exact), atol=1e-3 * np.abs(exact).max())
    rho = np.hypot(*V[F].mean(axis=1)[:, :2].T)
    closed = (C @ (1.0 / rho))[interior] / vertex_area[interior]
    assert np.abs(closed).max() < 1e-3 * np.abs(exact).max() / R


def test_coupled_sigma2_step_minimizes_with_the_fd_checked_gradient():
    V, F, fr, angle = _torus_with_exact_k1(16, 8)
    s = 1.6
    coupling = RowCountCoupling(F, fr, angle, len(V), s, weight=5.0)
    rng = np.random.default_rng(7)
    sigma2 = rng.uniform(1.3, 1.5, len(F))
    direction = rng.normal(size=len(F))
    h = 1e-6
    fd = (coupling.energy(sigma2 + h * direction) - coupling.energy(sigma2 - h * direction)) / (2 * h)
    assert np.isclose(coupling.gradient(sigma2) @ direction, fd, rtol=1e-6)
    # the step is the stationary point of Σ A (σ2 − σ̂2)² + E_c
    hat = rng.uniform(1.3, 1.5, len(F))
    step = coupling.step(hat)
    total_grad = 2 * fr.area * (step - hat) + coupling.gradient(step)
    assert np.abs(total_grad).max() < 1e-8 * np.abs(2 * fr.area * (hat - s)).max()
    # a σ2 with curl((s − σ2) k2) = 0, s − σ2 ∝ 1/ρ, costs nothing
    rho = np.hypot(*V[F].mean(axis=1)[:, :2].T)
    assert coupling.energy(s - 14.0 / rho) < 1e-4 * coupling.energy(np.full(len(F), 1.4))   # O(h²) left


def _row_count_spread(V, F, sigma2, s=1.6, nu=40):
    """Per meridian (a column of faces at one u), the relative spread of the rows across it per
    unit angle, (s − σ2) ρ (Eq. 10: σ2 / μ2 = (s − σ2) / (w_r (s − 1))): 0 when they can be counted."""
    c = V[F].mean(axis=1)
    u = np.arctan2(c[:, 1], c[:, 0])
    column = np.clip(((u - u.min()) / np.ptp(u) * nu).astype(int), 0, nu - 1)
    count = (s - sigma2) * np.hypot(c[:, 0], c[:, 1])
    mean = np.bincount(column, count) / np.bincount(column)
    spread = np.sqrt(np.bincount(column, (count - mean[column]) ** 2) / np.bincount(column))
    return float(np.median(spread / mean))


def test_integrability_phase_makes_the_rows_countable_along_k1():
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg=(0, 60), v_deg=(-30, 30), nu=40, nv=20)
    _, _, _, plain = flatten(V, F, spacing_integrability_weight=0.0)
    _, _, _, coupled = flatten(V, F)                      # the default: the coupled phase runs
    assert plain.coupled_iterations == 0 and coupled.coupled_iterations > 0
    assert coupled.converged and not coupled.folded.any()
    before, after = _row_count_spread(V, F, plain.sigma[:, 1]), _row_count_spread(V, F, coupled.sigma[:, 1])
    assert after < before / 1.4
    # the last phase is Eq. 3 alone: the bounds hold as they do without the coupling, σ1 takes
    # the torus's Gauss curvature instead of σ2 (it spreads over more of its range)
    assert bad_pct(coupled) == bad_pct(plain) == (0.0, 0.0)
    assert np.ptp(coupled.sigma[:, 0]) > 1.5 * np.ptp(plain.sigma[:, 0])


def test_max_iterations_caps_the_row_count_phase_and_the_paper_iteration_together():
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg=(0, 60), v_deg=(-30, 30), nu=40, nv=20)
    # without the residual stop, which would end the paper's iteration before the cap here
    _, _, _, capped = flatten(V, F, max_iterations=10, residual_tolerance=0.0)
    assert capped.iterations == 10 and capped.coupled_iterations == 5 and not capped.converged
    _, _, _, one = flatten(V, F, max_iterations=1)
    assert one.iterations == 1 and one.coupled_iterations == 0


def test_row_curl_operator_leaves_out_vertices_where_k1_is_not_defined():
    V, F, fr, angle = _torus_with_exact_k1(12, 6)
    C_all, _ = row_curl_operator(F, fr, angle, len(V))
    defined = np.ones(len(F), dtype=bool)
    defined[::7] = False
    C, _ = row_curl_operator(F, fr, angle, len(V), defined)
    touches_undefined = np.zeros(len(V), dtype=bool)
    touches_undefined[F[~defined].ravel()] = True
    rows = np.asarray(abs(C).sum(axis=1)).ravel() > 0
    rows_all = np.asarray(abs(C_all).sum(axis=1)).ravel() > 0
    assert not rows[touches_undefined].any()
    assert np.array_equal(rows, rows_all & ~touches_undefined)
    assert abs(C - C_all)[rows].sum() == 0                        # the kept rows are unchanged


def test_integrability_weight_is_refused_below_zero():
    with pytest.raises(ValueError):
        SolverSettings(spacing_integrability_weight=-1.0)
    V, F, fr, angle = _torus_with_exact_k1(6, 3)
    with pytest.raises(ValueError, match="weight"):
        RowCountCoupling(F, fr, angle, len(V), 1.6, weight=0.0)


def test_the_residual_stop_ends_at_the_first_iterate_that_fits_the_bounds_to_its_tolerance():
    # A saddle of 5,000 faces from a coarse start: the paper's stop creeps on along a valley of
    # Eq. 3; the residual stop ends once √(E / area) ≤ ε and every face is within the bounds to ε.
    V, F = surfaces.saddle(size=80.0, rings=28)
    eps = 1e-3
    fr, lf, solver, early = flatten(V, F, coarse_faces=1000, residual_tolerance=eps)
    *_, full = flatten(V, F, coarse_faces=1000, residual_tolerance=0.0)
    area = fr.area.sum()
    assert early.converged and full.converged and not early.folded.any()
    assert early.energy <= eps * eps * area
    (lo1, hi1), (lo2, hi2) = BOUNDS
    assert bounds_deviation(early.sigma[:, 0], lo1, hi1).max() <= eps
    assert bounds_deviation(early.sigma[:, 1], lo2, hi2).max() <= eps
    # the iterate before it did not fit yet: capped one iteration earlier, the same path has not stopped
    assert early.iterations > 1
    *_, before = flatten(V, F, coarse_faces=1000, residual_tolerance=eps, max_iterations=early.iterations - 1)
    assert not before.converged and before.uv.tobytes() != early.uv.tobytes()
    assert early.iterations < full.iterations and full.energy < early.energy
    assert bad_pct(early) == (0.0, 0.0)


def test_the_residual_stop_needs_every_face_within_the_bounds_not_only_a_small_energy():
    # _fits is given the energy: a map whose faces all sit 10 % below the lower bound does not fit,
    # whatever energy it is told; the converged map scaled by 1 does.
    V, F = surfaces.saddle(size=80.0, rings=16)
    _, _, solver, result = flatten(V, F, coarse_faces=1000, residual_tolerance=1e-3)
    assert solver._fits(result.uv, 0.0)
    assert not solver._fits(0.9 * result.uv / BOUNDS[0][0], 0.0)


def test_a_subdivided_mesh_starts_from_its_own_coarse_level_without_decimation(monkeypatch):
    from ribbond.design import flatten as flatten_module
    from ribbond.design.refine import refine
    from ribbond.design.subdivision import coarser_level

    V0, F0 = surfaces.sphere_cap(radius=80.0, half_angle_deg=20, rings=8)
    fine = refine(V0, F0, 2)                                  # as the intake refines a scan
    V, F = fine.V, fine.F

    def no_decimation(*args, **kwargs):
        raise AssertionError("a subdivided mesh was decimated")
    monkeypatch.setattr(flatten_module.igl, "decimate", no_decimation)
    fr, lf, solver, res = flatten(V, F, coarse_faces=len(F0))
    start = solver.coarse_start()
    assert np.all(solver._signed_area(start) > 0)            # midpoints of an unfolded map fold nothing
    # every new vertex of the last split sits at the middle of its edge's ends in the plane
    _, S = coarser_level(F, len(V))
    np.testing.assert_allclose(S @ start[: S.shape[1]], start, rtol=0, atol=1e-9)
    assert res.converged and not res.folded.any()
    assert bad_pct(res) == (0.0, 0.0)
    assert res.energy / fr.area.sum() < 1e-6


def test_the_decimated_coarse_mesh_does_not_move_with_a_1e_12_nudge():
    # a regular grid: libigl's edge collapses tie, and unsnapped each of five nudges gave another
    # coarse mesh (so another start and another iteration count)
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg=(0, 60), v_deg=(-30, 30), nu=60, nv=30)   # 3600 faces
    settings = SolverSettings(coarse_faces=600)
    U, G, birth, prolong = BoundedFlattener(V, F, np.zeros(len(F)), BOUNDS, settings).coarse_mesh()
    assert prolong is None and len(G) <= 600
    for seed in range(3):
        rng = np.random.default_rng(seed)
        nudged_V = V * (1.0 + 1e-12 * rng.standard_normal(V.shape))
        U2, G2, birth2, _ = BoundedFlattener(nudged_V, F, np.zeros(len(F)), BOUNDS, settings).coarse_mesh()
        assert np.array_equal(G2, G) and np.array_equal(U2, U) and np.array_equal(birth2, birth)
