"""Principal curvatures per face, against analytic surfaces (κ = 1/r for spheres and cylinders).

The exact principal curvatures and k1 directions of the test surfaces are evaluated at the face
centroids (``exact_curvature``); the accuracy measures are the issue's: on faces whose exact
anisotropy (|κ1| − |κ2|)/(|κ1| + |κ2|) exceeds 0.3, the angle between the estimated and the exact
k1 direction and the relative error of κ1, boundary faces included (and also looked at alone).
"""

from dataclasses import dataclass

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.curvature import face_curvature
from ribbond.design.frames import face_frames


# -- exact curvature of the analytic surfaces ------------------------------------------------------

@dataclass
class Exact:
    kappa1: np.ndarray     # (m,) signed, largest |κ| (design-format sign: > 0 bulging toward n)
    kappa2: np.ndarray     # (m,)
    d1: np.ndarray         # (m, 3) unit k1 direction (NaN at umbilics)


def _graph_exact(x, y, fx, fy, fxx, fxy, fyy):
    """z = f(x, y) with n up: κ are the eigenvalues of II v = κ I v, II = −Hess f / W."""
    m = len(x)
    W = np.sqrt(1 + fx ** 2 + fy ** 2)
    I = np.empty((m, 2, 2))
    I[:, 0, 0], I[:, 0, 1], I[:, 1, 0], I[:, 1, 1] = 1 + fx ** 2, fx * fy, fx * fy, 1 + fy ** 2
    II = np.empty((m, 2, 2))
    II[:, 0, 0], II[:, 0, 1], II[:, 1, 0], II[:, 1, 1] = fxx, fxy, fxy, fyy
    II = -II / W[:, None, None]    # the centre of curvature above the surface (on +n): κ < 0
    Li = np.linalg.inv(np.linalg.cholesky(I))                     # I = L Lᵀ
    k, U = np.linalg.eigh(Li @ II @ np.swapaxes(Li, 1, 2))
    vecs = np.swapaxes(Li, 1, 2) @ U                              # parameter-space eigenvectors
    first = np.abs(k[:, 1]) >= np.abs(k[:, 0])
    v = np.where(first[:, None], vecs[:, :, 1], vecs[:, :, 0])
    d = v[:, :1] * np.column_stack([np.ones(m), np.zeros(m), fx]) \
        + v[:, 1:] * np.column_stack([np.zeros(m), np.ones(m), fy])
    return Exact(np.where(first, k[:, 1], k[:, 0]), np.where(first, k[:, 0], k[:, 1]),
                 d / np.linalg.norm(d, axis=1)[:, None])


def exact_curvature(kind, V, F, **p):
    """Exact principal curvatures and k1 direction at the face centroids (projected on the surface).

    kind: "saddle" (kappa_x, kappa_y: z = (κx x² − κy y²)/2, n up), "torus" (R, r; n outward),
    "cylinder" (radius; axis z, n outward), "sphere" (radius; n outward: umbilic, no direction).
    """
    C = V[F].mean(axis=1)
    m = len(C)
    if kind == "saddle":
        kx, ky = p["kappa_x"], p["kappa_y"]
        x, y = C[:, 0], C[:, 1]
        return _graph_exact(x, y, kx * x, -ky * y, np.full(m, kx), np.zeros(m), np.full(m, -ky))
    if kind == "torus":
        R, r = p["R"], p["r"]
        u = np.arctan2(C[:, 1], C[:, 0])
        v = np.arctan2(C[:, 2], np.hypot(C[:, 0], C[:, 1]) - R)
        meridian = np.full(m, 1 / r)                          # around the tube, along ∂/∂v
        parallel = np.cos(v) / (R + r * np.cos(v))            # along ∂/∂u
        dm = np.column_stack([-np.sin(v) * np.cos(u), -np.sin(v) * np.sin(u), np.cos(v)])
        dp = np.column_stack([-np.sin(u), np.cos(u), np.zeros(m)])
        first = np.abs(meridian) >= np.abs(parallel)
        return Exact(np.where(first, meridian, parallel), np.where(first, parallel, meridian),
                     np.where(first[:, None], dm, dp))
    if kind == "cylinder":
        d = np.column_stack([-C[:, 1], C[:, 0], np.zeros(m)])
        return Exact(np.full(m, 1 / p["radius"]), np.zeros(m), d / np.linalg.norm(d, axis=1)[:, None])
    if kind == "sphere":
        k = np.full(m, 1 / p["radius"])
        return Exact(k, k.copy(), np.full((m, 3), np.nan))
    raise ValueError(kind)


def boundary_faces(V, F):
    """(m,) bool: faces with a vertex on the boundary."""
    E = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    key, count = np.unique(E[:, 0] * len(V) + E[:, 1], return_counts=True)
    on = np.zeros(len(V), bool)
    on[np.concatenate([key[count == 1] // len(V), key[count == 1] % len(V)])] = True
    return on[F].any(axis=1)


def k1_errors(V, F, fr, c, ex, threshold=0.3):
    """Direction errors (degrees) and κ1 relative errors on the anisotropic faces, and which of
    those faces are boundary faces."""
    aniso = (np.abs(ex.kappa1) - np.abs(ex.kappa2)) / (np.abs(ex.kappa1) + np.abs(ex.kappa2))
    sel = aniso > threshold
    d = ex.d1 - np.einsum("ij,ij->i", ex.d1, fr.n)[:, None] * fr.n    # into the face plane
    d /= np.linalg.norm(d, axis=1)[:, None]
    est = fr.to_world(np.column_stack([np.cos(c.angle), np.sin(c.angle)]))
    ang = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", d, est)), 0, 1)))
    rel = np.abs(c.kappa1 - ex.kappa1) / np.abs(ex.kappa1)
    return ang[sel], rel[sel], boundary_faces(V, F)[sel]


def curv(V, F):
    fr = face_frames(V, F)
    return fr, face_curvature(V, F, fr)


def test_sphere_cap_has_both_curvatures_one_over_r():
    r = 60.0
    _, c = curv(*surfaces.sphere_cap(radius=r, half_angle_deg=40, rings=16))
    assert np.allclose(c.kappa1, 1 / r, rtol=0.02)
    assert np.allclose(c.kappa2, 1 / r, rtol=0.02)
    assert np.all(np.abs(c.alignment) < 0.02 / r)          # umbilic: nothing to align with


def test_cylinder_k1_is_the_circumference_with_kappa_one_over_r():
    r = 40.0
    V, F = surfaces.cylinder_patch(radius=r, n_around=60, n_along=12)
    fr, c = curv(V, F)
    assert np.allclose(c.kappa1, 1 / r, rtol=0.03)    # 2° facets: the fit is within a few %
    assert np.all(np.abs(c.kappa2) < 0.01 / r)
    d = fr.to_world(np.column_stack([np.cos(c.angle), np.sin(c.angle)]))
    # Around the axis (z): no z component, and perpendicular to the radius.
    centre = V[F].mean(axis=1)
    radial = centre * [1, 1, 0] / np.linalg.norm(centre[:, :2], axis=1)[:, None]
    assert np.degrees(np.arcsin(np.abs(d[:, 2]).max())) < 0.5
    assert np.abs(np.einsum("ij,ij->i", d, radial)).max() < np.sin(np.radians(0.5))


def test_reversing_the_winding_flips_the_sign():
    V, F = surfaces.sphere_cap(radius=50.0, half_angle_deg=30, rings=10)
    _, c = curv(V, F)
    _, c_rev = curv(V, F[:, ::-1])
    assert np.all(c.kappa1 > 0) and np.all(c_rev.kappa1 < 0)
    assert np.allclose(c.kappa1, -c_rev.kappa1)


def test_torus_outer_equator_curvatures():
    R, r = 50.0, 20.0
    V, F = surfaces.torus_patch(R, r, u_deg=(0, 40), v_deg=(-20, 20), nu=60, nv=40)
    fr, c = curv(V, F)
    centre = V[F].mean(axis=1)
    v = np.arctan2(centre[:, 2], np.hypot(centre[:, 0], centre[:, 1]) - R)
    inner = np.abs(v) < np.radians(10)
    assert np.allclose(c.kappa1[inner], 1 / r, rtol=0.03)                       # around the tube
    assert np.allclose(c.kappa2[inner], np.cos(v[inner]) / (R + r * np.cos(v[inner])), rtol=0.05)


def test_largest_magnitude_wins_on_a_saddle_and_keeps_its_sign():
    kx, ky = 1 / 40, 1 / 100
    V, F = surfaces.saddle(size=20.0, kappa_x=kx, kappa_y=ky, rings=8)
    fr, c = curv(V, F)
    # z = (kx x² − ky y²)/2 with n = +z: a valley along x (centre of curvature on the +n side,
    # so κ < 0) and a ridge along y (κ > 0). Away from the centre the curvatures fall (by 9 % at
    # the rim along x), so the comparison is with the exact values at the face centroids.
    ex = exact_curvature("saddle", V, F, kappa_x=kx, kappa_y=ky)
    assert np.all(c.kappa1 < 0) and np.all(c.kappa2 > 0)
    assert np.allclose(c.kappa1, ex.kappa1, rtol=0.03)
    assert np.allclose(c.kappa2, ex.kappa2, rtol=0.05)
    centre = np.linalg.norm(V[F].mean(axis=1)[:, :2], axis=1) < 3.0
    assert np.allclose(c.kappa1[centre], -kx, rtol=0.02)
    d = fr.to_world(np.column_stack([np.cos(c.angle), np.sin(c.angle)]))
    near = np.linalg.norm(V[F].mean(axis=1)[:, :2], axis=1) < 3.0
    seen_from_above = np.abs(np.arctan2(d[near, 1], d[near, 0]))
    assert np.all(np.minimum(seen_from_above, np.pi - seen_from_above) < np.radians(2))  # along x
    # With the magnitudes swapped, k1 is along y and positive.
    V2, F2 = surfaces.saddle(size=20.0, kappa_x=ky, kappa_y=kx, rings=8)
    _, c2 = curv(V2, F2)
    assert np.all(c2.kappa1 > 0)
    assert np.allclose(c2.kappa1, exact_curvature("saddle", V2, F2, kappa_x=ky, kappa_y=kx).kappa1,
                       rtol=0.03)


def test_normal_curvature_follows_euler():
    V, F = surfaces.cylinder_patch(radius=30.0, n_around=20, n_along=8)
    _, c = curv(V, F)
    for t in np.radians([0, 30, 60, 90]):
        d = np.column_stack([np.cos(c.angle + t), np.sin(c.angle + t)])
        expect = c.kappa1 * np.cos(t) ** 2 + c.kappa2 * np.sin(t) ** 2
        assert np.allclose(c.normal_curvature(d), expect, atol=1e-12)


# -- the default estimator against the exact curvature ----------------------------------------------

SADDLES = [  # size, κx, κy, rings
    (160.0, 1 / 60, 1 / 60, 16), (160.0, 1 / 60, 1 / 60, 24), (160.0, 1 / 60, 1 / 60, 40),
    (80.0, 1 / 40, 1 / 100, 8), (80.0, 1 / 40, 1 / 100, 16), (80.0, 1 / 40, 1 / 100, 32),
    (60.0, 1 / 100, 1 / 30, 12), (60.0, 1 / 100, 1 / 30, 24),
]
TORI = [  # u range, v range, nu, nv (R 50, r 20)
    ((0, 60), (-30, 30), 30, 15), ((0, 60), (-30, 30), 60, 30), ((0, 60), (-30, 30), 120, 60),
    ((0, 90), (-45, 45), 60, 30), ((0, 90), (45, 225), 40, 40),   # the last: over the inner side
]


def saddle_case(size, kx, ky, rings):
    V, F = surfaces.saddle(size, kx, ky, rings=rings)
    return V, F, exact_curvature("saddle", V, F, kappa_x=kx, kappa_y=ky)


def torus_case(u_deg, v_deg, nu, nv):
    V, F = surfaces.torus_patch(50.0, 20.0, u_deg, v_deg, nu, nv)
    return V, F, exact_curvature("torus", V, F, R=50.0, r=20.0)


@pytest.mark.parametrize("case", SADDLES, ids=lambda c: f"{c[0]:g}mm-kx{1 / c[1]:g}-ky{1 / c[2]:g}-r{c[3]}")
def test_saddle_k1_direction_and_magnitude_match_the_exact_ones(case):
    V, F, ex = saddle_case(*case)
    fr, c = curv(V, F)
    ang, rel, bnd = k1_errors(V, F, fr, c, ex)
    assert len(ang) > 40 and bnd.any()
    # Measured: median ≤ 0.08°, p95 ≤ 0.44°, boundary p95 ≤ 0.75°, κ1 p95 ≤ 3.4 %.
    assert np.median(ang) < 0.15 and np.percentile(ang, 95) < 0.8
    assert np.median(ang[bnd]) < 0.4 and np.percentile(ang[bnd], 95) < 1.0
    assert np.median(rel) < 0.02 and np.percentile(rel, 95) < 0.05


@pytest.mark.parametrize("case", TORI, ids=lambda c: f"u{c[0][1]}-v{c[1][0]}..{c[1][1]}-{c[2]}x{c[3]}")
def test_torus_k1_direction_and_magnitude_match_the_exact_ones(case):
    V, F, ex = torus_case(*case)
    fr, c = curv(V, F)
    ang, rel, bnd = k1_errors(V, F, fr, c, ex)
    assert len(ang) > 0.5 * len(F) and bnd.any()
    # Measured: median ≤ 0.02°, p95 ≤ 0.23°, max ≤ 0.93° (boundary), κ1 within 1.01 %.
    assert np.median(ang) < 0.05 and np.percentile(ang, 95) < 0.5 and ang.max() < 1.5
    assert np.percentile(ang[bnd], 95) < 1.0
    assert rel.max() < 0.015


def test_torus_kappa2_matches_the_exact_one():
    V, F, ex = torus_case((0, 90), (45, 225), 40, 40)    # κ2 changes sign across v = 90°
    _, c = curv(V, F)
    err = np.abs(c.kappa2 - ex.kappa2) * 20.0              # in units of κ1 = 1/r
    inner = ~boundary_faces(V, F)
    # Measured: 0.3 % of κ1 inside, 2.8 % on the boundary faces (quadric fit: 6 % and 9 %).
    assert err[inner].max() < 0.006 and err.max() < 0.04


@pytest.mark.parametrize("n_around,n_along", [(20, 8), (40, 20), (80, 40)])
def test_cylinder_kappa_is_one_over_r_within_one_percent_everywhere(n_around, n_along):
    r = 40.0
    V, F = surfaces.cylinder_patch(r, 120.0, 60.0, n_around, n_along)
    fr, c = curv(V, F)
    ang, rel, bnd = k1_errors(V, F, fr, c, exact_curvature("cylinder", V, F, radius=r))
    assert len(ang) == len(F) and bnd.any()
    assert rel.max() < 0.01                                     # boundary faces included
    assert np.abs(c.kappa2).max() < 1e-3 / r
    assert ang.max() < 0.01


@pytest.mark.parametrize("radius,half_angle,rings", [(60.0, 40, 8), (60.0, 40, 16), (60.0, 40, 32),
                                                    (40.0, 90, 24)])
def test_sphere_caps_have_both_curvatures_one_over_r_within_one_percent(radius, half_angle, rings):
    V, F = surfaces.sphere_cap(radius, half_angle, rings)
    _, c = curv(V, F)
    # Boundary faces included: there one-sided normals would halve κ without the correction.
    assert np.abs(c.kappa1 * radius - 1).max() < 0.01
    assert np.abs(c.kappa2 * radius - 1).max() < 0.01


def test_errors_shrink_with_the_resolution():
    errs = []
    for rings in (16, 40):
        V, F, ex = saddle_case(160.0, 1 / 60, 1 / 60, rings)
        fr, c = curv(V, F)
        ang, rel, _ = k1_errors(V, F, fr, c, ex)
        errs.append((np.median(ang), np.percentile(ang, 95), np.median(rel)))
    assert all(hi < 0.6 * lo for lo, hi in zip(*errs))


# -- against libigl's quadric fit (the reference, method="quadric") ---------------------------------

@pytest.mark.parametrize("make", [lambda: saddle_case(160.0, 1 / 60, 1 / 60, 24),
                                  lambda: saddle_case(80.0, 1 / 40, 1 / 100, 16),
                                  lambda: saddle_case(60.0, 1 / 100, 1 / 30, 12),
                                  lambda: torus_case((0, 60), (-30, 30), 60, 30),
                                  lambda: torus_case((0, 90), (45, 225), 40, 40)],
                         ids=["sym-saddle-r24", "saddle-r16", "saddle-r12", "torus-60x30", "torus-inner"])
def test_at_least_as_accurate_as_the_quadric_fit_and_agrees_with_it(make):
    V, F, ex = make()
    fr = face_frames(V, F)
    new, ref = face_curvature(V, F, fr), face_curvature(V, F, fr, method="quadric")
    a_new, r_new, _ = k1_errors(V, F, fr, new, ex)
    a_ref, r_ref, _ = k1_errors(V, F, fr, ref, ex)
    assert np.median(a_new) <= np.median(a_ref) + 0.01
    assert np.percentile(a_new, 95) <= np.percentile(a_ref, 95)
    assert np.percentile(r_new, 95) <= np.percentile(r_ref, 95)
    # And the two estimates agree with each other.
    d = np.mod(new.angle - ref.angle, np.pi)
    diff = np.degrees(np.minimum(d, np.pi - d))
    aniso = (np.abs(ex.kappa1) - np.abs(ex.kappa2)) / (np.abs(ex.kappa1) + np.abs(ex.kappa2)) > 0.3
    assert np.median(diff[aniso]) < 0.6 and np.percentile(diff[aniso], 95) < 4.0
    assert np.median(np.abs(new.kappa1 / ref.kappa1 - 1)) < 0.05   # the quadric fit: up to 3 % off


def test_the_quadric_fit_is_still_available():
    r = 60.0
    _, F = V_F = surfaces.sphere_cap(radius=r, half_angle_deg=40, rings=16)
    fr = face_frames(*V_F)
    c = face_curvature(*V_F, fr, method="quadric")
    assert np.allclose(c.kappa1, 1 / r, rtol=0.02) and np.allclose(c.kappa2, 1 / r, rtol=0.02)


# -- robustness and input checks ----------------------------------------------------------------------

def test_a_vertex_of_no_face_changes_nothing():
    V, F = surfaces.saddle(40.0, rings=6)
    _, c = curv(V, F)
    _, c2 = curv(np.vstack([V, [[1e3, 0.0, 0.0]]]), F)
    assert np.allclose(c.shape_operator, c2.shape_operator, rtol=0, atol=1e-15)


def test_a_single_triangle_is_flat():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2]])
    _, c = curv(V, F)
    assert np.all(np.isfinite(c.shape_operator)) and np.allclose(c.shape_operator, 0)


def test_a_noisy_mesh_gives_finite_values():
    rng = np.random.default_rng(3)
    V, F = surfaces.sphere_cap(50.0, 60, rings=12)
    V = V + rng.normal(scale=0.2, size=V.shape)
    _, c = curv(V, F)
    assert np.all(np.isfinite(c.shape_operator))
    assert abs(np.median(c.kappa1) * 50 - 1) < 0.2


def test_more_smoothing_steps_tame_vertex_noise():
    rng = np.random.default_rng(7)
    V, F = surfaces.cylinder_patch(30.0, 120.0, 60.0, 120, 48)
    V = V + rng.normal(scale=0.01, size=V.shape)          # 2 % of the 0.5 mm edges
    fr = face_frames(V, F)
    ex = exact_curvature("cylinder", V, F, radius=30.0)
    med = [np.median(k1_errors(V, F, fr, face_curvature(V, F, fr, smoothing=k), ex)[0])
           for k in (1, 4, 8)]
    assert med[0] > 2 * med[1] > 4 * med[2]
    # Measured 3.6°, 0.85°, 0.35° (the quadric fit: 0.17°; 16 steps: 0.14°).
    assert med[2] < 0.6


def test_smoothing_steps_keep_the_curvature_of_a_cylinder_and_a_sphere():
    # Tensors move between face and vertex frames by rotation, not projection (which would
    # shrink κ by cos² of the 6° between neighbouring facets at every step).
    V, F = surfaces.cylinder_patch(40.0, 120.0, 60.0, 20, 8)
    c = face_curvature(V, F, face_frames(V, F), smoothing=16)
    assert np.abs(c.kappa1 * 40 - 1).max() < 0.005 and np.abs(c.kappa2).max() < 1e-3 / 40
    V, F = surfaces.sphere_cap(60.0, 40, 8)
    c = face_curvature(V, F, face_frames(V, F), smoothing=16)
    assert np.abs(c.kappa1 * 60 - 1).max() < 0.005 and np.abs(c.kappa2 * 60 - 1).max() < 0.005


def test_no_smoothing_is_the_raw_per_face_fit():
    V, F = surfaces.sphere_cap(60.0, 40, 16)
    _, c = curv(V, F)
    c0 = face_curvature(V, F, face_frames(V, F), smoothing=0)
    assert np.abs(c0.kappa1 * 60 - 1).max() < 0.01 and not np.allclose(c0.kappa1, c.kappa1)


def test_bad_input_is_refused_with_a_message():
    V, F = surfaces.cylinder_patch(n_around=6, n_along=3)
    fr = face_frames(V, F)
    with pytest.raises(ValueError, match="method"):
        face_curvature(V, F, fr, method="jets")
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        face_curvature(V[:, :2], F, fr)
    with pytest.raises(ValueError, match=r"\(m, 3\)"):
        face_curvature(V, F[:, :2], fr)
    with pytest.raises(ValueError, match="outside"):
        face_curvature(V, np.where(F == F.max(), len(V), F), fr)
    with pytest.raises(ValueError, match="frames"):
        face_curvature(V, F[:-1], fr)
    with pytest.raises(ValueError, match="finite"):
        face_curvature(np.where(V == V.max(), np.nan, V), F, fr)
    with pytest.raises(ValueError, match="integer"):
        face_curvature(V, F.astype(float), fr)
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="smoothing"):
            face_curvature(V, F, fr, smoothing=bad)
