"""Principal curvatures per face, against analytic surfaces (κ = 1/r for spheres and cylinders)."""

import numpy as np

from ribbond.design import surfaces
from ribbond.design.curvature import face_curvature
from ribbond.design.frames import face_frames


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
    # so κ < 0) and a ridge along y (κ > 0).
    assert np.allclose(c.kappa1, -kx, rtol=0.05)
    assert np.allclose(c.kappa2, ky, rtol=0.1)
    d = fr.to_world(np.column_stack([np.cos(c.angle), np.sin(c.angle)]))
    near = np.linalg.norm(V[F].mean(axis=1)[:, :2], axis=1) < 3.0
    seen_from_above = np.abs(np.arctan2(d[near, 1], d[near, 0]))
    assert np.all(np.minimum(seen_from_above, np.pi - seen_from_above) < np.radians(2))  # along x
    # With the magnitudes swapped, k1 is along y and negative.
    _, c2 = curv(*surfaces.saddle(size=20.0, kappa_x=ky, kappa_y=kx, rings=8))
    assert np.allclose(c2.kappa1, kx, rtol=0.05)


def test_normal_curvature_follows_euler():
    V, F = surfaces.cylinder_patch(radius=30.0, n_around=20, n_along=8)
    _, c = curv(V, F)
    for t in np.radians([0, 30, 60, 90]):
        d = np.column_stack([np.cos(c.angle + t), np.sin(c.angle + t)])
        expect = c.kappa1 * np.cos(t) ** 2 + c.kappa2 * np.sin(t) ** 2
        assert np.allclose(c.normal_curvature(d), expect, atol=1e-12)
