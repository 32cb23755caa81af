"""The k1 line field (KCPS13 with curvature alignment and λ, §4.3)."""

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.curvature import face_curvature
from ribbond.design.frames import face_frames
from ribbond.design.line_field import connection_laplacian, curvature_line_field


def line_angle_deg(a, b):
    """Angle between two line directions (mod π), degrees in [0, 90]."""
    d = np.mod(a - b, np.pi)
    return np.degrees(np.minimum(d, np.pi - d))


def field(V, F, lam=0.0):
    fr = face_frames(V, F)
    c = face_curvature(V, F, fr)
    return fr, c, curvature_line_field(V, F, fr, c, smoothing_lambda=lam)


def test_cylinder_field_runs_around_the_circumference():
    V, F = surfaces.cylinder_patch(radius=40.0, n_around=40, n_along=12)
    fr, c, lf = field(V, F)
    assert lf.aligned and not lf.umbilic.any()
    assert np.abs(lf.direction[:, 2]).max() < np.sin(np.radians(0.1))


def test_torus_field_follows_the_tube():
    R, r = 50.0, 20.0
    V, F = surfaces.torus_patch(R, r, u_deg=(0, 60), v_deg=(-30, 30), nu=60, nv=30)
    fr, c, lf = field(V, F)
    centre = V[F].mean(axis=1)
    u = np.arctan2(centre[:, 1], centre[:, 0])
    v = np.arctan2(centre[:, 2], np.hypot(centre[:, 0], centre[:, 1]) - R)
    tube = np.column_stack([-np.sin(v) * np.cos(u), -np.sin(v) * np.sin(u), np.cos(v)])  # ∂/∂v
    cos = np.abs(np.einsum("ij,ij->i", lf.direction, tube))
    dev = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    # Meridians are not parallel along the parallels (those are not geodesics), so smoothing
    # (λ = 0) pulls the field a little off them, most at the patch's ends.
    assert dev.mean() < 1.0 and dev.max() < 3.0


def test_a_plane_is_umbilic_and_gets_a_parallel_field():
    V, F = surfaces.plane_disk(rings=6)
    fr, c, lf = field(V, F)
    assert not lf.aligned and lf.umbilic.all()
    d = lf.direction
    assert np.abs(np.abs(d @ d[0]) - 1).max() < 1e-6


def test_a_sphere_cap_is_marked_umbilic():
    V, F = surfaces.sphere_cap(radius=50.0, half_angle_deg=30, rings=10)
    _, _, lf = field(V, F)
    assert lf.umbilic.all()


def test_the_connection_energy_vanishes_on_a_parallel_field():
    V, F = surfaces.plane_disk(rings=5)
    fr = face_frames(V, F)
    A = connection_laplacian(V, F, fr)
    assert abs(A - A.conj().T).max() < 1e-12
    world = np.array([np.cos(0.7), np.sin(0.7), 0.0])
    z = np.exp(2j * np.arctan2(fr.e2 @ world, fr.e1 @ world))     # one direction everywhere
    assert abs(np.vdot(z, A @ z)) < 1e-9 * np.vdot(z, z).real
    rng = np.random.default_rng(1)
    w = rng.normal(size=len(F)) + 1j * rng.normal(size=len(F))
    assert np.vdot(w, A @ w).real > 0


def test_negative_lambda_smooths_less():
    rng = np.random.default_rng(7)
    V, F = surfaces.cylinder_patch(radius=30.0, n_around=40, n_along=16)
    V = V + rng.normal(scale=0.05, size=V.shape)            # noisy curvature directions
    fr = face_frames(V, F)
    c = face_curvature(V, F, fr)
    dev = [line_angle_deg(curvature_line_field(V, F, fr, c, smoothing_lambda=lam).angle, c.angle).mean()
           for lam in (0.0, -10.0, -1000.0)]
    assert dev[0] > dev[1] > dev[2]
    # The smooth field is nearer the true circumferential direction than the raw noisy one.
    smooth = curvature_line_field(V, F, fr, c).direction
    raw = fr.to_world(np.column_stack([np.cos(c.angle), np.sin(c.angle)]))
    assert np.abs(smooth[:, 2]).mean() < np.abs(raw[:, 2]).mean()


def test_positive_lambda_is_refused():
    V, F = surfaces.cylinder_patch(n_around=8, n_along=4)
    fr = face_frames(V, F)
    with pytest.raises(ValueError, match="smoothing_lambda"):
        curvature_line_field(V, F, fr, face_curvature(V, F, fr), smoothing_lambda=0.5)
